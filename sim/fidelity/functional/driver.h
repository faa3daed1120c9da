// The driver: feeds a fragment stream (a trace file or a built-in scene) to
// the functional models and collects counters, images and timing.
#pragma once
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "rtl_models/functional/breakdown.h"
#include "rtl_models/functional/compressibility.h"
#include "rtl_models/functional/fragment_source.h"
#include "rtl_models/golden/golden_model.h"
#include "sim/fidelity/common/run_outcome.h"
#include "traces/format/trace.h"

namespace ropsim {

/// Reads the whole input into memory (for benchmarks and tests).
struct FragmentList {
  TraceHeader header;
  std::vector<Fragment> fragments;
};
FragmentList load_fragments(const InputSpec& in);

struct FunctionalRun : RunOutcome {
  int threads = 1;                          ///< host threads of the model
  std::optional<Image> reference;           ///< the reference method's image, when asked for
  std::unique_ptr<RunBreakdown> breakdown;  ///< per draw and per pixel, when asked for
  CompressionStats compression;             ///< the final buffers' compressibility (cfg.compression)
};

/// Runs the functional model of cfg.method over the input; with
/// with_reference also the A-buffer reference on the same stream. threads:
/// the model's host threads, 0 for host_threads() (--threads); the result is
/// the same for every count.
/// breakdown: also split the counters by draw and sum them per pixel
/// (RunBreakdown; not for the reference method, which has no ROP).
FunctionalRun run_functional(const InputSpec& in, const GoldenConfig& cfg, bool with_reference = false, int threads = 0,
                             const BreakdownRequest& breakdown = {});

/// Peak resident set size of this process in bytes (VmHWM), 0 if unknown.
size_t peak_rss_bytes();

/// Refuses up front (UserError) an input whose A-buffer reference is already
/// known to need more than --memory-limit (memory_budget.h).
void check_reference_estimate(const FragmentSource& src);

}  // namespace ropsim
