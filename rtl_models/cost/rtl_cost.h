// Silicon cost of LK's units from the synthesis of the reference RTL
// (rtl_models/rtl, scripts/synth.sh): the committed sweep
// docs/data/rtl_synth_sweep.csv is compiled into the binary, and a design's
// units are looked up in it, or, for parameters it does not hold, estimated
// by a per-module structural model fitted to it (docs/rtl.md "Cost of a
// design"). No SystemC, no hardware config: the driver maps a design onto
// these modules' parameters.
#pragma once
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "rtl_models/algo/numerics.h"

namespace ropsim {

using RtlParams = std::map<std::string, int64_t>;  ///< NAME -> value, as synth.sh passes them

/// One synthesis run of the sweep (one CSV row).
struct RtlSynthRow {
  std::string module;  ///< rop_alpha_ref, ...
  std::string params_text;
  RtlParams params;
  int64_t cells = 0, flipflops = 0, transistors = 0, nand2_eq = 0, levels = 0;
};

/// Parses a synthesis CSV (scripts/synth.sh's columns); a malformed row
/// throws UserError naming `name` and the line.
std::vector<RtlSynthRow> parse_rtl_synth_csv(const std::string& text, const std::string& name);
/// The committed sweep, docs/data/rtl_synth_sweep.csv, as built into ropsim.
const std::vector<RtlSynthRow>& rtl_synth_table();
/// The modules the cost knows, in pipeline order.
const std::vector<std::string>& rtl_cost_modules();

/// Where an estimate comes from.
enum class CostSource { kSweep, kModel, kNone };
const char* to_string(CostSource s);

/// A module instance's cost. Absent figures (nullopt) come with the reason.
struct RtlCost {
  CostSource source = CostSource::kNone;
  std::optional<double> nand2_eq;    ///< NAND2 equivalents (transistors / 4)
  std::optional<int64_t> flipflops;  ///< D flip-flops
  std::optional<double> levels;      ///< gate levels of the deepest stage
  double nand2_error_bound = 0;      ///< model: the documented relative bound (0 for a sweep row)
  double levels_error_bound = 0;
  std::string reason;  ///< why a figure is absent, or which sweep row stands for it
};

/// The documented relative error bounds of a module's model (its largest
/// leave-one-out error on the sweep, rounded up; docs/rtl.md). The test
/// refits without each row and checks the prediction stays within them.
struct RtlModelBounds {
  double nand2 = 0, levels = 0;
};
RtlModelBounds rtl_model_bounds(const std::string& module);

/// The cost of `module` with `params` (every parameter the module takes):
/// the sweep row when the table holds these parameters, else the module's
/// model fitted to `table`'s rows, else absent with the reason (an unknown
/// module, a parameter outside the modelled range, too few rows to fit).
RtlCost rtl_cost(const std::string& module, const RtlParams& params, const std::vector<RtlSynthRow>& table);
inline RtlCost rtl_cost(const std::string& module, const RtlParams& params) {
  return rtl_cost(module, params, rtl_synth_table());
}
/// The model alone (no lookup), fitted to `table`: what the tests hold out.
RtlCost rtl_cost_model(const std::string& module, const RtlParams& params, const std::vector<RtlSynthRow>& table);

/// One sweep row held out: the module's model refitted to the other rows
/// predicts it (`ropsim config --silicon-check`, the SiliconCost tests).
struct HeldOutError {
  std::string module, params;
  std::optional<double> nand2_error;   ///< (model - synthesis) / synthesis; none outside the model's range
  std::optional<double> levels_error;  ///< the same for the levels; none when too few rows remain to fit
  std::string reason;                  ///< why an error is absent
};
std::vector<HeldOutError> rtl_model_check(const std::vector<RtlSynthRow>& table);

/// A design as the cost sees it: the instances of each LK unit per ROP and
/// their parameters. The driver fills it from the hardware design and the
/// run (rtl_design_of, cycle_report.h); the design's defaults live in
/// HwConfig only, so a field left 0 here is outside every model (null).
struct RtlDesign {
  std::string name;           ///< the design (file or "built-in defaults")
  std::string method = "lk";  ///< the run's method
  bool lk_selection = true;   ///< the method selects samples as lk does (tracker, sorter, alpha refs)
  bool blend_pass = false;    ///< the method has blend passes (a unit without reference RTL)
  int rop_units = 0;
  int spp = 0;
  int width = 0, height = 0;  ///< pixels (the Hilbert index's order)
  int alpha_ref_lanes = 0, alpha_ref_stages = 0;
  int depth_lanes = 0, depth_stages = 0;
  int tracker_stages = 0;
  int opacity_lanes = 0;
  std::string sorter_kind;
  Numerics numerics;
};

/// One unit instance of a ROP.
struct UnitCost {
  std::string unit;    ///< hilbert_index, depth_compare, tracker_update, sorter, alpha_ref, opacity_test
  std::string module;  ///< its reference RTL module
  std::string params;  ///< its parameters, "NAME=VALUE ..."
  RtlCost cost;
};

/// Every LK unit of one ROP, their sum and the whole design's.
struct DesignCost {
  std::vector<UnitCost> units;
  std::optional<double> rop_nand2_eq, total_nand2_eq;
  std::optional<int64_t> rop_flipflops, total_flipflops;
  std::optional<double> rop_levels;  ///< the deepest unit's
  std::string reason;                ///< why the sums are absent ("" when present)
};
DesignCost design_cost(const RtlDesign& d);

}  // namespace ropsim
