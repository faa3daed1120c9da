// Run reports: one JSON printer and one human-summary printer, so the model
// code never prints (docs/reports.md lists every field with its unit).
#pragma once
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "rtl_models/cost/rtl_cost.h"
#include "sim/fidelity/functional/driver.h"
#include "sim/report/report_fields.h"
#include "traces/format/frame_stats.h"

namespace ropsim {

nlohmann::ordered_json counters_to_json(const Counters& c);
nlohmann::ordered_json numerics_to_json(const Numerics& n);

/// The report's "fidelity" field's meaning (every report writes it).
inline constexpr const char* kFidelityMeaning =
    "`functional` (the golden model), `cycle` (the SystemC pipeline), `sampled` (the pipeline on samples of the "
    "input, livepoints.h) or `approximate` (the analytical model, approximate.h)";

struct ReportContext {
  std::string command_line;
  InputSpec input;
  GoldenConfig config;
  std::vector<std::string> outputs;
  /// The hardware design the run stands for, as the silicon cost sees it
  /// (rtl_design_of in cycle_report.h; the run's spp, screen, method and
  /// numerics are filled in by the report). Absent: `silicon` says so.
  std::optional<RtlDesign> design;
  /// The input frame's statistics (frame_of): the report's `frame.*` when
  /// the frame has draw states.
  std::optional<FrameStats> frame;
};

/// The statistics of a trace input's frame (streams the trace once); none
/// for a scene or mesh input.
std::optional<FrameStats> frame_of(const InputSpec& in);

/// The "silicon" section: the NAND2-equivalent estimate, flip-flops and
/// logic levels of each LK unit of one ROP of the design, per ROP and for
/// the whole design (rtl_cost.h); null figures come with the reason.
void put_silicon(Fields s, const ReportContext& ctx, const TraceHeader& header);

/// The functional report; with a sink, also each field's description.
nlohmann::ordered_json functional_report(const ReportContext& ctx, const FunctionalRun& run, FieldSink* sink = nullptr);

/// The run's counters split by the trace's draw ids (--per-draw): the
/// report's `draws[]`, each draw's counters (and, from the cycle model, the
/// cycles attributed to it, and with dram_listed its DRAM bytes of each buffer
/// b whose bit is set); they add up to the run's counters (and timing).
void put_draws(Fields r, const RunBreakdown& b, bool with_cycles, bool with_blend, bool with_slab,
               uint32_t dram_listed = 0);
/// The same as CSV (--draw-csv): draw, [cycles,] then every counter, then
/// dram_bytes_read.BUFFER and dram_bytes_written.BUFFER per listed buffer,
/// one row per draw, ascending.
std::string draws_csv(const RunBreakdown& b, bool with_cycles, uint32_t dram_listed = 0);

/// A short human summary of a functional run (a few lines).
std::string functional_summary(const ReportContext& ctx, const FunctionalRun& run);

}  // namespace ropsim
