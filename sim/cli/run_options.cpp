#include "sim/cli/run_options.h"

#include <fmt/format.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>

#include "rtl_models/algo/slab.h"
#include "rtl_models/config/hw_config.h"
#include "rtl_models/top/memory_estimate.h"
#include "sim/cli/cli_common.h"
#include "sim/fidelity/cycle/cycle_run.h"
#include "sim/fidelity/fidelity.h"
#include "sim/fidelity/functional/driver.h"
#include "sim/fidelity/run.h"
#include "sim/fidelity/sampled/livepoint_file.h"
#include "sim/image/heat_map.h"
#include "sim/image/image_io.h"
#include "sim/report/cycle_report.h"
#include "sim/report/report.h"
#include "sim/report/run_report.h"
#include "traces/format/trace.h"
#include "util/host_threads.h"

namespace ropsim::cli {

/// The run's fidelity (--fidelity, checked against fidelity_names()).
Fidelity fidelity_of(const RunOpts& o) {
  const auto f = parse_fidelity(o.fidelity);
  invariant(f.has_value(), "--fidelity is checked against fidelity_names()");
  return *f;
}

/// The design, with the numerics flags over its [numerics].
HwConfig resolve_design(const RunOpts& o, CLI::App& sub) {
  HwConfig hw = resolve_hw_config(o.hw, o.hw_sets);
  if (sub.count("--hash-bits")) hw.numerics.hash_bits = o.num.hash_bits;
  if (sub.count("--alpha-bits")) hw.numerics.alpha_bits = o.num.alpha_bits;
  if (sub.count("--surface-id-bits")) hw.numerics.surface_id_bits = o.num.surface_id_bits;
  return hw;
}

/// The input: --trace, or the scene flags.
InputSpec resolve_input(const RunOpts& o, CLI::App& sub) {
  InputSpec in;
  in.repeat = o.repeat;
  if (!o.trace.empty()) {
    in.trace_path = o.trace;
    for (const char* f : kSceneFlags)
      if (sub.count(f)) throw UserError(std::string(f) + " applies to --scene, not --trace");
  } else {
    in.scene.name = o.scene;
    in.scene.spp = o.spp;
    in.scene.width = o.width;
    in.scene.height = o.height;
    in.scene.seed = o.scene_seed;
  }
  return in;
}

/// The method and its numerics (the design's).
GoldenConfig resolve_method(const RunOpts& o, const HwConfig& hw) {
  GoldenConfig cfg;
  parse_method(o.method, cfg.method);
  cfg.numerics = hw.numerics;
  cfg.formats = hw.blend.formats;
  // The timing fidelities take the design's compression themselves
  // (on_design); a functional run measures it only when asked, as its store
  // then keeps each depth's plane key.
  if (o.compressibility) cfg.compression = hw.compression.setup();
  cfg.seed = o.seed;
  cfg.slab_layers = o.slab_layers;
  cfg.slab_bits = o.slab_bits;
  if (validate_slab(o.slab_layers, o.slab_bits)) {
    if (o.slab_layers < 1 || o.slab_layers > kMaxSlabLayers)
      throw UserError("--slab-layers " + std::to_string(o.slab_layers) + ": must be in [1, 16]");
    throw UserError("--slab-bits " + std::to_string(o.slab_bits) + ": must be in [1, 64]");
  }
  parse_enderton_selection(o.enderton_selection, cfg.enderton_selection);
  return cfg;
}

/// The samples per pixel of an input: a scene's flag, a trace's header.
int input_spp(const RunOpts& o, const InputSpec& in) {
  if (!in.from_trace()) return o.spp;
  return int(TraceReader(in.trace_path).header().spp);
}

/// Refuses, before any work, a design whose model does not fit in
/// --memory-limit (memory_estimate.h; the model charges it again as it is
/// built). copies: the pipelines alive at once (sampled workers).
void check_design_memory(const InputSpec& in, const GoldenConfig& cfg, const HwConfig& hw, MemoryModel model,
                         uint32_t copies) {
  const TraceHeader h = open_fragments(in)->header();
  check_model_memory(hw, estimate_memory(hw, MemoryShape{h.width, h.height, h.spp, cfg.method, copies}, model));
}

void add_input_and_method_options(CLI::App* run, RunOpts* ro_, CLI::Option* opt_trace) {
  RunOpts* ro = ro_;
  run->add_option("--scene", ro->scene, "Built-in scene (default cloth): " + join(scene_names()))
      ->check(CLI::IsMember(scene_names()))
      ->excludes(opt_trace);
  run->add_option("--method", ro->method, "Method: " + join(method_names()) + " (default lk)")
      ->check(CLI::IsMember(method_names()));
  run->add_option("--spp", ro->spp, "Samples per pixel for --scene: 1, 2, 4, 8, 16, 32 or 64 (default 16)")
      ->check(CLI::IsMember({1, 2, 4, 8, 16, 32, 64}));
  run->add_option("--width", ro->width, "Scene width in pixels (default: the scene's)")
      ->check(in_range(1u, kMaxScreenSide));
  run->add_option("--height", ro->height, "Scene height in pixels (default: the scene's)")
      ->check(in_range(1u, kMaxScreenSide));
  run->add_option("--scene-seed", ro->scene_seed, "Seed of the scene generator (default 1)");
  run->add_option("--seed", ro->seed, "Seed of the methods' hash-based random numbers (default 1)");
  run->add_option("--slab-layers", ro->slab_layers, "slab: k, layers per pixel (1..16, default 8)");
  run->add_option("--slab-bits", ro->slab_bits, "slab: b, bits of each layer's coverage mask (1..64, default 32)");
  run->add_option("--enderton-selection", ro->enderton_selection,
                  "enderton and its variants choose R among: depth-first (the depth survivors; default) or original "
                  "(all covered samples, before the depth test)")
      ->check(CLI::IsMember({"depth-first", "original"}));
  run->add_option("--hash-bits", ro->num.hash_bits,
                  "Alpha-reference hash datapath width, bits (8..32; default: the design's numerics.hash_bits, 32)")
      ->check(in_range(8, 32));
  run->add_option("--alpha-bits", ro->num.alpha_bits,
                  "Opacity fixed-point precision, bits (1..32; default: the design's numerics.alpha_bits, 32)")
      ->check(in_range(1, 32));
  run->add_option("--surface-id-bits", ro->num.surface_id_bits,
                  "Surface id register width, bits (1..32; default: the design's numerics.surface_id_bits, 32)")
      ->check(in_range(1, 32));
}

void add_sampling_options(CLI::App* run, RunOpts* ro) {
  const SamplingParams dp;
  run->add_option("--sample-units", ro->sampling.units,
                  "sampled: units K, placed every N / K fragments (default " + std::to_string(dp.units) + ")")
      ->check(in_range(uint64_t{1}, uint64_t{1} << 40));
  run->add_option("--sample-size", ro->sampling.unit_fragments,
                  "sampled: fragments U per measured window (default " + std::to_string(dp.unit_fragments) + ")")
      ->check(in_range(uint64_t{1}, uint64_t{1} << 40));
  run->add_option("--sample-warmup", ro->sampling.warmup_fragments,
                  "sampled: fragments W simulated in detail before each window (default " +
                      std::to_string(dp.warmup_fragments) + ")");
  run->add_option(
      "--sample-cooldown", ro->sampling.cooldown_fragments,
      "sampled: fragments C simulated after each window (default " + std::to_string(dp.cooldown_fragments) + ")");
  run->add_option("--sample-warming", ro->sampling.warming_fragments,
                  "sampled: fragments T before each warm-up that may warm the caches tag-only (default " +
                      std::to_string(dp.warming_fragments) + ")");
  run->add_option("--sample-warming-reach", ro->sampling.warming_reach,
                  "sampled: per design, warm tag-only from where the touches before the warm-up reach R x the "
                  "design's cache lines in distinct lines, at most T back (default " +
                      fmt::format("{}", dp.warming_reach) + ")")
      ->check(in_range(0.0, 1e6))
      ->type_name("R");
}

void add_design_options(CLI::App* run, RunOpts* ro) {
  run->add_option(
         "--hw", ro->hw,
         "Hardware design file (TOML, docs/config.md; default: built-in defaults); functional: only its [numerics], "
         "blend.*_format and [compression]")
      ->check(CLI::ExistingFile);
  run->add_option("--hw-set", ro->hw_sets,
                  "Override one design parameter, section.key=value; repeatable (functional: numerics.*, "
                  "blend.*_format and compression.* only)");
}

}  // namespace ropsim::cli
