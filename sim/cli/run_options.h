// The flags `ropsim run` and `ropsim livepoints` take, and what they
// resolve to: the input, the method and its numerics, the design.
#pragma once
#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>
#include <vector>

#include "rtl_models/config/hw_config.h"
#include "rtl_models/functional/breakdown.h"
#include "rtl_models/golden/golden_model.h"
#include "rtl_models/top/memory_estimate.h"
#include "sim/fidelity/fidelity.h"
#include "sim/fidelity/sampled/livepoints.h"
#include "traces/format/trace.h"

namespace ropsim::cli {

struct RunOpts {
  std::string trace, scene = "cloth", method = "lk", fidelity = "functional", report;
  std::string hw, vcd, vcd_window;
  std::vector<std::string> hw_sets;
  uint32_t repeat = 1;
  std::vector<std::string> outs;
  int spp = 16;
  uint32_t width = 0, height = 0;
  uint64_t seed = 1, scene_seed = 1;
  int slab_layers = MethodConfig{}.slab_layers, slab_bits = MethodConfig{}.slab_bits;
  std::string enderton_selection = "depth-first";
  Numerics num;
  bool vs_reference = false, quiet = false, lockstep = false, progress = false;
  bool compressibility = false;  ///< functional: measure the final surfaces' compressed sizes
  uint64_t stats_interval = 0;
  std::string stats_csv;
  SamplingParams sampling;
  std::string livepoints;   ///< sampled: read the live-points from this library
  int jobs = 0;             ///< sampled: worker processes (0: every core)
  std::string library_out;  ///< the livepoints verb: the library to write
  bool per_draw = false;    ///< the counters split by draw id, in the report
  std::string draw_csv;     ///< ... and as CSV
  std::string maps;         ///< the per-pixel maps' folder
  BreakdownRequest breakdown() const { return {per_draw || !draw_csv.empty(), !maps.empty()}; }
};

/// The run's fidelity (--fidelity, checked against fidelity_names()).
Fidelity fidelity_of(const RunOpts& o);

/// The sampling flags (a library fixes them when it is built).
inline constexpr const char* kSamplingFlags[] = {"--sample-units",    "--sample-size",    "--sample-warmup",
                                                 "--sample-cooldown", "--sample-warming", "--sample-warming-reach"};
/// The flags that choose a scene input.
inline constexpr const char* kSceneFlags[] = {"--scene", "--spp", "--width", "--height", "--scene-seed"};

/// The design, with the numerics flags over its [numerics].
HwConfig resolve_design(const RunOpts& o, CLI::App& sub);
/// The input: --trace, or the scene flags.
InputSpec resolve_input(const RunOpts& o, CLI::App& sub);
/// The method and its numerics (the design's).
GoldenConfig resolve_method(const RunOpts& o, const HwConfig& hw);
/// The samples per pixel of an input: a scene's flag, a trace's header.
int input_spp(const RunOpts& o, const InputSpec& in);
/// Refuses, before any work, a design whose model does not fit in
/// --memory-limit (memory_estimate.h; the model charges it again as it is
/// built). copies: the pipelines alive at once (sampled workers).
void check_design_memory(const InputSpec& in, const GoldenConfig& cfg, const HwConfig& hw, MemoryModel model,
                         uint32_t copies = 1);

/// The options a run and a live-point library share: the scene input, the
/// method and its numerics.
void add_input_and_method_options(CLI::App* run, RunOpts* ro, CLI::Option* opt_trace);
/// The sampling flags.
void add_sampling_options(CLI::App* run, RunOpts* ro);
/// --hw and --hw-set.
void add_design_options(CLI::App* run, RunOpts* ro);

}  // namespace ropsim::cli
