#include "sim/report/cycle_report.h"

#include <fmt/format.h>

#include <map>
#include <variant>

#include "sim/image/image_io.h"
#include "util/errors.h"
#include "util/hex.h"

namespace ropsim {

namespace {

/// The functional part of a timed run (a CycleRun or an ApproxRun), for the
/// functional report and summary it extends.
template <class Run>
FunctionalRun as_functional(const Run& run, const std::optional<Image>& reference) {
  FunctionalRun f;
  f.header = run.header;
  f.counters = run.counters;
  f.kind_fragments = run.kind_fragments;
  f.image = run.image;
  f.state_bytes = run.state_bytes;
  f.wall_seconds = run.wall_seconds;
  f.reference = reference;
  return f;
}

/// A sampled run's functional part: the library's exact counters and image.
FunctionalRun as_functional(const LivePoints& lib, double wall_seconds, const std::optional<Image>& reference) {
  FunctionalRun f;
  f.header = lib.header;
  f.counters = lib.counters;
  f.image = lib.image;
  f.wall_seconds = wall_seconds;
  f.reference = reference;
  return f;
}

}  // namespace

nlohmann::ordered_json cycle_report(const ReportContext& ctx, const CycleRun& run,
                                    const std::optional<Image>& reference, FieldSink* sink) {
  nlohmann::ordered_json j = functional_report(with_design(ctx, run.stats.hw), as_functional(run, reference), sink);
  Fields r(j, sink);
  r.put("fidelity", "cycle", "-", kFidelityMeaning);
  put_hardware(r.obj("hardware"), run.stats.hw);
  put_cycle_stats(r.obj("timing"), run.stats);
  Fields host = r.obj("host");
  host.put("sim_seconds", run.sim_seconds, "s", "cycle: sc_start alone");
  host.put("simulated_fragments_per_second",
           run.sim_seconds > 0 ? double(run.counters.fragments) / run.sim_seconds : 0.0, "1/s",
           "cycle: fragments over sim_seconds");
  if (run.breakdown && run.breakdown->per_draw())
    put_draws(r, *run.breakdown, true, has_blend_pass(ctx.config.method) || !run.header.draws.empty(),
              ctx.config.method == Method::kSlab, run.stats.listed);
  return j;
}

nlohmann::ordered_json sampled_report(const ReportContext& ctx, const LivePoints& lib, const SampledRun& s,
                                      const HwConfig& hw, double wall_seconds, const LibrarySource& from,
                                      const std::optional<Image>& reference, FieldSink* sink) {
  nlohmann::ordered_json j = functional_report(with_design(ctx, hw), as_functional(lib, wall_seconds, reference), sink);
  Fields r(j, sink);
  r.put("fidelity", "sampled", "-", kFidelityMeaning);
  put_hardware(r.obj("hardware"), hw);
  Fields t = r.obj("timing");
  auto ci = [](const Estimate& e) { return std::vector<double>{e.low, e.high}; };
  t.put("total_cycles", s.total_cycles.value, "cycles",
        "sampled: estimate of the cycles to the end of the final cache flush (N x the units' mean per fragment, plus "
        "the last unit's drain and flush)");
  t.put("total_cycles_ci95", ci(s.total_cycles), "cycles",
        "sampled: 95 % confidence interval [low, high] of total_cycles (Student t over the units)");
  t.put("frame_time_us", s.total_cycles.value / (hw.clock.frequency_ghz * 1e3), "us",
        "sampled: total_cycles at the configured clock");
  Fields d = t.obj("dram");
  d.put("bytes_read", s.dram_bytes_read.value, "bytes", "sampled: estimate of the DRAM bytes read, every buffer");
  d.put("bytes_read_ci95", ci(s.dram_bytes_read), "bytes", "sampled: its 95 % confidence interval [low, high]");
  d.put("bytes_written", s.dram_bytes_written.value, "bytes",
        "sampled: estimate of the DRAM bytes written, every buffer (the units' lines made dirty, each written once)");
  d.put("bytes_written_ci95", ci(s.dram_bytes_written), "bytes", "sampled: its 95 % confidence interval [low, high]");
  // Compression and Hi-Z: the units' counts per fragment times N (writes: by
  // the lines the windows made dirty), as the cycle model reports them.
  if (s.stats.compression_on) put_compression_traffic(t.obj("compression"), s.stats.compression, hw);
  put_bottleneck(t, s.stats.bottleneck);
  t.put("memory_bound", s.stats.memory_bound, "bool", "the bottleneck is the DRAM's bandwidth (bottleneck_kind)");
  t.empty_array("units");
  for (const auto& u : s.stats.units) {
    Fields j = t.item("units");
    put_unit_identity(j, u);
    put_unit_activity(j, u, s.stats.total_cycles);
  }
  Fields sp = t.obj("sampling");
  sp.put("library", from.path.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(from.path), "-",
         "sampled: the live-point library file read (ropsim livepoints), or null when this run recorded its own");
  sp.put(
      "input_digest", hex64(lib.input.digest), "-",
      "sampled: XXH3-64 of the input the live-points were recorded from (a trace file's bytes, a scene's fragments)");
  sp.put("whole", lib.whole, "bool",
         "sampled: the input was small (its units would have simulated at least half of it in detail), so one unit "
         "simulated it whole: the figures are the full cycle run's, exactly");
  sp.put("units", s.units, "units", "sampled: sampling units simulated in detail (K)");
  sp.put("unit_fragments", lib.params.unit_fragments, "fragments", "sampled: fragments per measured window (U)");
  sp.put("warmup_fragments", lib.params.warmup_fragments, "fragments",
         "sampled: fragments simulated in detail before each window (W, at most)");
  sp.put("cooldown_fragments", lib.params.cooldown_fragments, "fragments",
         "sampled: fragments simulated after each window but the last (C)");
  sp.put("warming_fragments", lib.params.warming_fragments, "fragments",
         "sampled: fragments before each warm-up warming the caches tag-only (T, at most)");
  sp.put("warming_reach", lib.params.warming_reach, "x cache lines",
         "sampled: per design, the warming starts where the touches before the warm-up reach R times the design's "
         "cache lines in distinct lines (R)");
  sp.put("fragments_warmed", s.fragments_warmed, "fragments",
         "sampled: fragments whose touches warmed the caches tag-only, summed over the units (this design)");
  sp.put("units_warming_short", s.units_warming_short, "units",
         "sampled: units whose warming stopped at T before reaching R x the cache lines (a larger T would warm "
         "them more)");
  sp.put("fragments", lib.fragments, "fragments", "sampled: the input's fragments (N)");
  sp.put("fragments_detailed", s.fragments_detailed, "fragments",
         "sampled: fragments the cycle model simulated (warm-ups, windows, cool-downs)");
  Fields host = r.obj("host");
  host.put("sampled_seconds", s.sim_seconds, "s",
           "sampled: the units' simulation, tag-only warming included (wall clock, with the workers)");
  host.put("sampled_cpu_seconds", s.cpu_seconds, "s",
           "sampled: the units' simulation, CPU time summed over this process and its workers");
  host.put("sampled_jobs", s.jobs, "processes", "sampled: worker processes that simulated the units (-j)");
  host.put("library_seconds", from.seconds, "s",
           "sampled: recording the live-points (one functional pass), or reading the library file");
  return j;
}

std::string sampled_summary(const ReportContext& ctx, const LivePoints& lib, const SampledRun& s, const HwConfig& hw,
                            double wall_seconds, const LibrarySource& from, const std::optional<Image>& reference) {
  std::string out =
      fmt::format("ropsim: {} | method {} | {}x{} @ {} spp | sampled on {}\n", ctx.input.describe(),
                  to_string(ctx.config.method), lib.header.width, lib.header.height, lib.header.spp, hw.name);
  auto line = [](const char* what, const Estimate& e, const char* unit) {
    return fmt::format("  {:<14} {:.0f} {} (95 % interval {:.0f} .. {:.0f}, +-{:.2f} %)\n", what, e.value, unit, e.low,
                       e.high, e.value > 0 ? 50.0 * (e.high - e.low) / e.value : 0.0);
  };
  out += line("total cycles", s.total_cycles, "cycles");
  out += line("DRAM read", s.dram_bytes_read, "bytes");
  out += line("DRAM written", s.dram_bytes_written, "bytes");
  if (s.stats.compression_on) {
    const CompressionTraffic& c = s.stats.compression;
    uint64_t before = 0, after = 0;
    for (size_t b = 0; b < size_t(kBuffers); ++b) {
      before += c.bytes_written_uncompressed[b] + c.bytes_read_uncompressed[b];
      after += c.bytes_written[b] + c.bytes_read[b];
    }
    out += fmt::format(
        "  compression (estimated): {} B of compressed-surface traffic moved as {} B; Hi-Z rejected {} of {} "
        "fragments\n",
        before, after, c.hiz_rejected, c.hiz_tests);
  }
  out += fmt::format("  {} units of {} fragments; {} of {} fragments simulated in detail ({:.1f} %)\n", s.units,
                     lib.params.unit_fragments, s.fragments_detailed, lib.fragments,
                     lib.fragments ? 100.0 * double(s.fragments_detailed) / double(lib.fragments) : 0.0);
  out += "  " + format_bottleneck(s.stats) + " (estimated)\n";
  out += "  bounds (cycles, estimated): " + format_bounds(s.stats.bottleneck) + "\n";
  if (reference) {
    const CompareResult cr = compare_images(lib.image, *reference);
    out += fmt::format("  vs reference: RMSE {:.3f} (8-bit units), PSNR {:.2f} dB\n", cr.rmse_8bit, cr.psnr_db);
  }
  out += fmt::format("  wall {:.3f} s ({} {:.3f} s, units {:.3f} s on {} process{})\n", wall_seconds,
                     from.path.empty() ? "live-points recorded in" : "library " + from.path + " read in", from.seconds,
                     s.sim_seconds, s.jobs, s.jobs == 1 ? "" : "es");
  for (const auto& o : ctx.outputs) out += "  wrote " + o + "\n";
  return out;
}

nlohmann::ordered_json approximate_report(const ReportContext& ctx, const ApproxRun& run,
                                          const std::optional<Image>& reference, FieldSink* sink) {
  nlohmann::ordered_json j = functional_report(with_design(ctx, run.stats.hw), as_functional(run, reference), sink);
  Fields r(j, sink);
  r.put("fidelity", "approximate", "-", kFidelityMeaning);
  const ApproxStats& s = run.stats;
  put_hardware(r.obj("hardware"), s.hw);
  put_approx_stats(r.obj("timing"), s, run.counters);
  return j;
}

std::string approximate_summary(const ReportContext& ctx, const ApproxRun& run, const std::optional<Image>& reference) {
  const ApproxStats& s = run.stats;
  std::string out = functional_summary(ctx, as_functional(run, reference));
  out += fmt::format("  approximate model ({}): {} cycles = {:.2f} us at {} GHz ({} in epochs, fill {}, flush {})\n",
                     s.hw.name, s.total_cycles, double(s.total_cycles) / (s.hw.clock.frequency_ghz * 1e3),
                     s.hw.clock.frequency_ghz, s.total_cycles - s.fill_cycles - s.flush_cycles, s.fill_cycles,
                     s.flush_cycles);
  out += fmt::format("  DRAM: {} B read, {} B written (tag-only)\n", s.dram.total_bytes_read(),
                     s.dram.total_bytes_written());
  if (s.compression_on) out += compression_summary(s.compression);
  std::string bounds;
  for (int b = 0; b < kApproxBounds; ++b)
    bounds += fmt::format("{}{} {:.0f}", b ? ", " : "", to_string(ApproxBound(b)), s.bound_cycles[size_t(b)]);
  out += "  model bounds (cycles, summed over the epochs): " + bounds + "\n";
  out += "  " + format_bottleneck(s.bottleneck) + "\n";
  out += "  bounds (cycles): " + format_bounds(s.bottleneck) + "\n";
  return out;
}

std::vector<FieldDoc> report_field_docs() {
  // The fields are described where they are written, so list them by writing
  // the reports of small runs that emit every field: lk (every unit) on a
  // scene, with the reference; a trace input's fields come from the context.
  FieldSink sink;
  InputSpec in;
  in.scene.name = "eight-layers";
  in.scene.spp = 4;
  in.scene.width = 16;
  in.scene.height = 16;
  MethodConfig m;
  ReportContext ctx;
  ctx.command_line = "ropsim run ...";
  ctx.input = in;
  ctx.config = m;
  ctx.design = rtl_design_of(HwConfig{});
  const FunctionalRun f = run_functional(in, m, true, 0, BreakdownRequest{true, false});
  {  // the compressibility fields: the same run with every surface compressed
    MethodConfig mc = m;
    mc.compression = HwConfig{}.compression.setup();
    mc.compression.depth = mc.compression.color = true;
    ReportContext cc = ctx;
    cc.config = mc;
    functional_report(cc, run_functional(in, mc, false), &sink);
  }
  functional_report(ctx, f, &sink);
  {  // a frame of draw states: its draw kinds (the fields do not depend on the values)
    FunctionalRun d = run_functional(in, m, false);
    d.header.draws = DrawTable({default_draw_state(0)});
    d.kind_fragments[size_t(DrawKind::kSrcOver)] = d.counters.fragments;
    ReportContext dc = ctx;
    dc.frame = FrameStats{};
    functional_report(dc, d, &sink);
  }
  CycleOptions with_draws;
  with_draws.breakdown.per_draw = true;
  const CycleRun c = run_cycle(in, m, HwConfig{}, with_draws);
  ctx.input.trace_path = "scene.rtr";
  cycle_report(ctx, c, f.reference, &sink);
  {  // compression and Hi-Z (the cycle model's traffic)
    HwConfig hc;
    hc.compression.depth = hc.compression.color = hc.hiz.enable = true;
    MethodConfig mc = m;
    mc.compression = hc.compression.setup();
    ReportContext cc = ctx;
    cc.config = mc;
    cycle_report(cc, run_cycle(in, mc, hc), f.reference, &sink);
  }
  // The fields only some methods write (the hashed coverage selection's,
  // slab's parameters and layers buffer).
  m.method = Method::kSlab;
  ctx.config = m;
  cycle_report(ctx, run_cycle(in, m, HwConfig{}, with_draws), f.reference, &sink);  // and its per-draw DRAM
  // A method with every kind of blend pass and render target: passes, targets,
  // the blend counters and unit.
  ctx.input.trace_path.clear();
  for (Method bm : {Method::kLkDepthAc, Method::kWboit, Method::kEndertonAc}) {
    ctx.config.method = m.method = bm;
    const FunctionalRun fb = run_functional(in, m, false);
    functional_report(ctx, fb, &sink);
    const CycleRun cb = run_cycle(in, m, HwConfig{}, with_draws);
    cycle_report(ctx, cb, std::nullopt, &sink);
  }
  // A sampled run's fields.
  {
    SamplingParams sp;
    sp.units = 2;
    sp.unit_fragments = 16;
    sp.warmup_fragments = 8;
    sp.cooldown_fragments = 8;
    sp.warming_fragments = 8;
    ctx.config = MethodConfig{};
    const LivePoints lib = record_livepoints(in, ctx.config, sp);
    sampled_report(ctx, lib, run_sampled(lib, HwConfig{}), HwConfig{}, 0.0, LibrarySource{"lib.rlp", 0.0}, std::nullopt,
                   &sink);
  }
  // An approximate run's fields (its method's buffers as above).
  ctx.config = MethodConfig{};
  approximate_report(ctx, run_approximate(in, ctx.config, HwConfig{}), std::nullopt, &sink);
  {  // with compression and Hi-Z (the same fields as the cycle model's)
    HwConfig hc;
    hc.compression.depth = hc.compression.color = hc.hiz.enable = true;
    ReportContext cc = ctx;
    cc.config.compression = hc.compression.setup();
    approximate_report(cc, run_approximate(in, cc.config, hc), std::nullopt, &sink);
  }
  return sink.docs();
}

std::string cycle_summary(const ReportContext& ctx, const CycleRun& run, const std::optional<Image>& reference) {
  const CycleStats& s = run.stats;
  std::string out = functional_summary(ctx, as_functional(run, reference));
  out += fmt::format(
      "  cycle model ({}): {} cycles = {:.2f} us at {} GHz; {:.3f} fragments/clock, {:.2f} samples/clock\n", s.hw.name,
      s.total_cycles, s.frame_time_us, s.hw.clock.frequency_ghz, s.fragments_per_clock, s.samples_per_clock);
  out += fmt::format("  DRAM: {} B read, {} B written, {:.1f} of {:.1f} GB/s; busiest channel {:.0f}% busy\n",
                     s.dram.total_bytes_read(), s.dram.total_bytes_written(), s.dram_achieved_gbps, s.dram_peak_gbps,
                     100 * s.dram_utilization);
  if (s.compression_on) out += compression_summary(s.compression);
  for (const auto& p : s.passes)
    out += fmt::format("  pass {}: {} cycles; DRAM {} B read, {} B written\n", p.name, p.total_cycles,
                       p.dram.total_bytes_read(), p.dram.total_bytes_written());
  out += "  " + format_bottleneck(s) + "\n";
  out += "  bounds (cycles): " + format_bounds(s.bottleneck) + "\n";
  out += fmt::format("  host: {:.3f} s simulated, {:.2f} M fragments/s\n", run.sim_seconds,
                     run.sim_seconds > 0 ? run.counters.fragments / run.sim_seconds / 1e6 : 0.0);
  return out;
}

}  // namespace ropsim
