#include "sim/report/report.h"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "rtl_models/algo/slab.h"
#include "rtl_models/functional/functional_rop.h"
#include "sim/image/image_io.h"
#include "sim/report/report_fields.h"
#include "traces/format/frame_stats.h"
#include "traces/format/trace.h"
#include "util/memory_budget.h"
#include "util/output_file.h"
#include "util/version.h"

namespace ropsim {

nlohmann::ordered_json counters_to_json(const Counters& c) {
  nlohmann::ordered_json j;
  put_counters(Fields(j, nullptr), c);
  return j;
}

void put_numerics(Fields f, const Numerics& n) {
  f.put("hash_bits", n.hash_bits, "bits", "width of the alpha-reference hash datapath (docs/numerics.md)");
  f.put("alpha_bits", n.alpha_bits, "bits", "fixed-point precision of the fragment opacity");
  f.put("surface_id_bits", n.surface_id_bits, "bits", "width of the per-pixel surface id register (wraps)");
}

nlohmann::ordered_json numerics_to_json(const Numerics& n) {
  nlohmann::ordered_json j;
  put_numerics(Fields(j, nullptr), n);
  return j;
}

namespace {
/// A figure or null (JSON).
template <class T>
nlohmann::ordered_json or_null(const std::optional<T>& v) {
  return v ? nlohmann::ordered_json(*v) : nlohmann::ordered_json(nullptr);
}
}  // namespace

/// A frame of draw states: its statistics by the draws' kinds
/// (frame_stats.h), whatever the method: what the frame is.
void put_frame_stats(Fields f, const FrameStats& s) {
  f.put("covered_samples", s.covered, "samples", "a frame of draw states: its fragments' covered samples");
  f.put("transparent_share", s.transparent_share(), "-",
        "a frame of draw states: the share of the covered samples that src-over and premultiplied-over draws cover");
  f.put("translucent_share", s.translucent_share(), "-",
        "a frame of draw states: the share of the covered samples that transparent fragments below alpha 1 cover");
  f.put("transparent_screen_share", s.transparent_screen_share(), "-",
        "a frame of draw states: the share of the screen's samples (width x height x spp) that a transparent "
        "fragment covers");
  f.put("transparent_depth_complexity", s.transparent_per_sample(), "fragments",
        "a frame of draw states: transparent fragments per sample they cover, the mean");
  f.put("transparent_fragments_per_pixel_max", s.transparent_max, "fragments",
        "a frame of draw states: the most transparent fragments in one pixel");
}

std::optional<FrameStats> frame_of(const InputSpec& in) {
  // Only a frame of draw states reports them (functional_report): another trace is
  // not read a second time.
  if (!in.from_trace() || TraceReader(in.trace_path).header().draws.empty()) return std::nullopt;
  return frame_stats_of(in.trace_path);
}

void put_silicon(Fields s, const ReportContext& ctx, const TraceHeader& header) {
  s.put("source", "docs/data/rtl_synth_sweep.csv", "-",
        "the synthesis the estimates come from: Yosys 0.23 generic flow (abc -g cmos2) of rtl_models/rtl, "
        "scripts/synth.sh (docs/rtl.md)");
  DesignCost cost;
  if (ctx.design) {
    RtlDesign d = *ctx.design;
    d.method = to_string(ctx.config.method);
    d.lk_selection = selection_of(ctx.config.method) == Method::kLk;
    d.blend_pass = has_blend_pass(ctx.config.method);
    d.spp = int(header.spp);
    d.width = int(header.width);
    d.height = int(header.height);
    d.numerics = ctx.config.numerics;
    cost = design_cost(d);
    s.put("design", d.name, "-",
          "the hardware design costed (a functional run: its --hw design, else the built-in one) with the run's spp, "
          "screen and numerics");
    s.put("rop_units", d.rop_units, "units", "distributor.rop_units: ROPs, each with one instance of every unit");
  } else {
    cost.reason = "no hardware design given to the report";
  }
  Fields units = s.obj("units");
  for (const UnitCost& u : cost.units) {
    Fields f = units.obj(u.unit);
    const std::string w = u.unit + ": ";
    f.put("module", u.module, "-", w + "its reference RTL module (rtl_models/rtl)");
    f.put("params", u.params, "-", w + "the module's parameters for this design");
    f.put("estimate", to_string(u.cost.source), "-",
          w + "sweep (a row of the synthesis sweep), model (the module's model fitted to the sweep, within "
              "error_bound) or none (the figures are null: see reason)");
    f.put("nand2_eq", or_null(u.cost.nand2_eq), "NAND2 eq.",
          w + "area of one instance: transistors / 4 of the NAND2/NOR2/inverter/D flip-flop netlist");
    f.put("flipflops", or_null(u.cost.flipflops), "flip-flops", w + "D flip-flops of one instance");
    f.put("levels", or_null(u.cost.levels), "gate levels",
          w + "longest gate path of its deepest pipeline stage (Yosys ltp -noff)");
    f.put("error_bound", u.cost.nand2_error_bound, "fraction",
          w + "model: the documented bound on the relative error of nand2_eq (0: a sweep row)");
    f.put("reason", u.cost.reason, "-", w + "why a figure is null, or the sweep row that stands for these parameters");
  }
  Fields rop = s.obj("per_rop");
  rop.put("nand2_eq", or_null(cost.rop_nand2_eq), "NAND2 eq.", "the LK units of one ROP, summed (null: see reason)");
  rop.put("flipflops", or_null(cost.rop_flipflops), "flip-flops", "their flip-flops, summed");
  rop.put("levels", or_null(cost.rop_levels), "gate levels", "the deepest stage of any of them");
  Fields total = s.obj("total");
  total.put("nand2_eq", or_null(cost.total_nand2_eq), "NAND2 eq.", "per_rop.nand2_eq x rop_units");
  total.put("flipflops", or_null(cost.total_flipflops), "flip-flops", "per_rop.flipflops x rop_units");
  s.put("reason", cost.reason, "-", "why the sums are null (\"\" when every unit has figures)");
}

nlohmann::ordered_json functional_report(const ReportContext& ctx, const FunctionalRun& run, FieldSink* sink) {
  nlohmann::ordered_json j;
  Fields r(j, sink);
  r.put("tool", "ropsim", "-", "`ropsim`");
  Fields v = r.obj("ropsim");
  v.put("version", ropsim_version(), "-", "the ropsim version that wrote the report");
  v.put("commit", ropsim_commit(), "-", "the source commit it was built from (git describe; \"unknown\" outside git)");
  r.put("report_version", 1, "-", "the report format's version");
  r.put("command", ctx.command_line, "-", "the command line");
  r.put("fidelity", "functional", "-", kFidelityMeaning);
  Fields in = r.obj("input");
  if (ctx.input.from_trace()) {
    in.put("trace", ctx.input.trace_path, "-", "the trace file read (a trace input)");
  } else {
    in.put("scene", ctx.input.scene.name, "-", "the built-in scene (a scene input)");
    in.put("scene_seed", ctx.input.scene.seed, "-", "the scene's seed (a scene input)");
  }
  in.put("scene_name", run.header.scene_name, "-", "the scene name in the header");
  in.put("width", run.header.width, "pixels", "screen width");
  in.put("height", run.header.height, "pixels", "screen height");
  in.put("spp", run.header.spp, "samples", "samples per pixel");
  r.put("method", to_string(ctx.config.method), "-", "the transparency method");
  r.put("seed", ctx.config.seed, "-",
        "the seed of the hash-based random numbers, in every report; the methods that draw them: enderton and its "
        "variants, naive, hashed, hashed-a2c, slab (the others ignore it)");
  if (selection_of(ctx.config.method) == Method::kEnderton)
    r.put("enderton_selection", to_string(ctx.config.enderton_selection), "-",
          "enderton and its variants: depth-first (R of the depth survivors) or original (R of the covered samples, "
          "before the depth test)");
  if (ctx.config.method == Method::kSlab) {
    Fields slab = r.obj("slab");
    slab.put("layers", ctx.config.slab_layers, "layers", "slab: k, layers per pixel");
    slab.put("bits", ctx.config.slab_bits, "bits", "slab: b, bits of each layer's coverage mask");
    slab.put("pixel_bytes", slab_pixel_bytes(ctx.config.slab_layers, ctx.config.slab_bits), "bytes",
             "slab: one pixel's layers in memory, k (4 + 6 + ceil(b / 8)) + 1");
  }
  put_numerics(r.obj("numerics"), ctx.config.numerics);
  put_silicon(r.obj("silicon"), ctx, run.header);
  // A frame of draw states: its blended draws' counts, whatever the method.
  const bool draw_states = !run.header.draws.empty();
  put_counters(r.obj("counters"), run.counters, has_blend_pass(ctx.config.method) || draw_states,
               ctx.config.method == Method::kSlab);
  uint64_t kinds = 0;
  for (uint64_t n : run.kind_fragments) kinds += n;
  if (draw_states && kinds > 0) {  // (a sampled run's library does not keep them)
    Fields k = r.obj("draw_kinds");
    for (int i = 0; i < kDrawKinds; ++i) {
      const DrawKind dk = DrawKind(i);
      const char* path = dk == DrawKind::kOpaque ? "z-buffer writes with the draw's own depth state (blend: written)"
                         : route_of(dk) == DrawRoute::kMethod
                             ? "the method's transparency (blend: blended)"
                             : "blended into the colour with the draw's own state, as blend does";
      std::string key = to_string(dk);
      std::replace(key.begin(), key.end(), '-', '_');
      k.put(key, run.kind_fragments[size_t(i)], "fragments",
            std::string("a frame of draw states: fragments of ") + to_string(dk) + " draws: " + path);
    }
  }
  if (draw_states && ctx.frame) put_frame_stats(r.obj("frame"), *ctx.frame);
  if (has_blend_pass(ctx.config.method)) {
    const PassList pl = run_passes(run.header, ctx.config.method);
    std::vector<std::string> names;
    for (int i = 0; i < pl.count; ++i) names.push_back(to_string(pl.pass[i]));
    r.put(
        "passes", names, "-",
        "methods with blend passes: the passes over the input, in order (prepass: a frame's opaque and blended draws; "
        "total_alpha, stochastic, accumulate, wboit)");
    Fields t = r.obj("render_targets");
    const bool prepass = runs_prepass(run.header, ctx.config.method);
    if (run_uses_transmittance(ctx.config.method, prepass))
      t.put("transmittance", to_string(ctx.config.formats.transmittance), "-",
            "the transmittance target's format (product of 1 - alpha per sample; +depth over a pre-pass: 0 where "
            "its stochastic pass wrote)");
    if (run_uses_accum(ctx.config.method, prepass))
      t.put("accum", to_string(target_formats(ctx.config).accum), "-",
            "the accumulation target's format in the functional store (alpha-weighted colour and alpha per "
            "sample; +ac over a pre-pass: its stochastic pass's colour and 1; blend: the framebuffer, rgba32f)");
  }
  if (ctx.config.method != Method::kReference) {
    // The surfaces' bytes a sample in memory (surface_bytes.h), as every
    // fidelity's traffic and compression count them.
    const SurfaceBytes sb = surface_bytes(run.header, store_targets(run.header, ctx.config));
    const bool prepass = runs_prepass(run.header, ctx.config.method);
    Fields s = r.obj("sample_bytes");
    s.put("depth", sb.of(Buffer::kDepth), "bytes", "one sample of the depth buffer in memory (binary32)");
    s.put("color", sb.of(Buffer::kColor), "bytes",
          "one sample of the colour buffer in memory: RGB binary16, or RGBA8 on a frame of an 8-bit target "
          "(blend keeps its framebuffer in accum)");
    if (run_uses_transmittance(ctx.config.method, prepass))
      s.put("transmittance", sb.of(Buffer::kTransmittance), "bytes",
            "one sample of the transmittance target in memory (its format)");
    if (run_uses_accum(ctx.config.method, prepass))
      s.put("accum", sb.of(Buffer::kAccum), "bytes",
            "one sample of the accumulation target in memory (its format; blend: the framebuffer, RGBA8 on an "
            "8-bit target, RGBA binary32 otherwise)");
  }
  if (ctx.config.compression.any() && run.compression.measured)
    put_compressibility(r.obj("compressibility"), run.compression, ctx.config.compression);
  Fields host = r.obj("host");
  host.put("wall_seconds", run.wall_seconds, "s", "the whole run: input, model(s), resolve");
  host.put("samples_per_second", run.wall_seconds > 0 ? double(run.counters.samples_tested) / run.wall_seconds : 0.0,
           "1/s", "samples tested over wall time");
  host.put("fragments_per_second", run.wall_seconds > 0 ? double(run.counters.fragments) / run.wall_seconds : 0.0,
           "1/s", "fragments over wall time");
  host.put("state_bytes", run.state_bytes, "bytes", "host memory of the per-pixel state");
  host.put("threads", run.threads, "threads",
           "host threads of the golden model (--threads; the result is the same for every count)");
  host.put("peak_rss_bytes", peak_rss_bytes(), "bytes", "peak resident set of the process (VmHWM)");
  host.put("memory_limit_bytes", memory_budget().limit(), "bytes",
           "--memory-limit: the most the growing state may take (default 80 % of physical memory; 0: none)");
  host.put(
      "memory_charged_peak_bytes", memory_budget().peak(), "bytes",
      "peak of the state charged against --memory-limit in this process: touched tiles, image, A-buffer, timing model");
  if (run.reference) {
    const CompareResult c = compare_images(run.image, *run.reference);
    Fields v = r.obj("vs_reference");
    v.put("rmse_8bit", c.rmse_8bit, "8-bit units",
          "with --vs-reference: RMSE of the image against the A-buffer reference of the same stream (linear, x 255)");
    v.put("psnr_db", std::isfinite(c.psnr_db) ? c.psnr_db : 999.0, "dB", "PSNR against the reference (999: identical)");
    v.put("max_error_8bit", c.max_error_8bit, "8-bit units", "largest channel error against the reference");
    v.put("bias_8bit", c.bias_8bit, "8-bit units",
          "mean signed error against the reference (image minus reference): a systematic darkening or brightening");
  }
  if (run.breakdown && run.breakdown->per_draw())
    put_draws(r, *run.breakdown, false, has_blend_pass(ctx.config.method) || !run.header.draws.empty(),
              ctx.config.method == Method::kSlab);
  r.put("outputs", ctx.outputs, "-", "files written");
  return j;
}

void put_draws(Fields r, const RunBreakdown& b, bool with_cycles, bool with_blend, bool with_slab,
               uint32_t dram_listed) {
  r.empty_array("draws");
  for (const auto& [id, d] : b.draws()) {
    Fields f = r.item("draws");
    f.put("draw", id, "-", "with --per-draw: the trace's draw id (one entry per draw that had a fragment, ascending)");
    if (with_cycles)
      f.put("cycles", d.cycles, "cycles",
            "cycle model, --per-draw: the cycles attributed to the draw, from each of its fragments' retirement back "
            "to the previous retirement (the draws' cycles add up to timing.pipeline_cycles)");
    put_counters(f.obj("counters"), d.counters, with_blend, with_slab);
    if (!dram_listed) continue;
    Fields dram = f.obj("dram");
    uint64_t read = 0, written = 0;
    for (int k = 0; k < kBuffers; ++k) {
      if (!((dram_listed >> k) & 1u)) continue;
      const std::string buf = to_string(Buffer(k));
      Fields x = dram.obj(buf);
      x.put("bytes_read", d.dram_read[size_t(k)], "bytes",
            "cycle model, --per-draw: DRAM bytes read for the " + buf +
                " buffer by the draw's cache misses (fills, and a compressed surface's state bits); the draws add up "
                "to timing.dram." +
                buf + ".bytes_read");
      x.put("bytes_written", d.dram_written[size_t(k)], "bytes",
            "cycle model, --per-draw: DRAM bytes written for the " + buf +
                " buffer from lines the draw wrote last (evictions and the final flush, state bits likewise); the "
                "draws add up to timing.dram." +
                buf + ".bytes_written");
      read += d.dram_read[size_t(k)];
      written += d.dram_written[size_t(k)];
    }
    dram.put("bytes_read", read, "bytes", "cycle model, --per-draw: the draw's DRAM bytes read, every buffer");
    dram.put("bytes_written", written, "bytes", "cycle model, --per-draw: the draw's DRAM bytes written, every buffer");
  }
}

std::string draws_csv(const RunBreakdown& b, bool with_cycles, uint32_t dram_listed) {
  std::string s = "draw";
  if (with_cycles) s += ",cycles";
  for (const StatDesc& d : counter_descs()) s += std::string(",") + d.name;
  for (int k = 0; k < kBuffers; ++k)
    if ((dram_listed >> k) & 1u) s += std::string(",dram_bytes_read.") + to_string(Buffer(k));
  for (int k = 0; k < kBuffers; ++k)
    if ((dram_listed >> k) & 1u) s += std::string(",dram_bytes_written.") + to_string(Buffer(k));
  s += "\n";
  for (const auto& [id, d] : b.draws()) {
    s += std::to_string(id);
    if (with_cycles) s += "," + std::to_string(d.cycles);
    d.counters.for_each([&](const char*, uint64_t v) { s += "," + std::to_string(v); });
    for (int k = 0; k < kBuffers; ++k)
      if ((dram_listed >> k) & 1u) s += "," + std::to_string(d.dram_read[size_t(k)]);
    for (int k = 0; k < kBuffers; ++k)
      if ((dram_listed >> k) & 1u) s += "," + std::to_string(d.dram_written[size_t(k)]);
    s += "\n";
  }
  return s;
}

std::string functional_summary(const ReportContext& ctx, const FunctionalRun& run) {
  const Counters& c = run.counters;
  std::string s = fmt::format("ropsim: {} | method {} | {}x{} @ {} spp\n", ctx.input.describe(),
                              to_string(ctx.config.method), run.header.width, run.header.height, run.header.spp);
  s += fmt::format("  fragments {}  samples tested {}  depth-passed {}  written {}\n", c.fragments, c.samples_tested,
                   c.samples_depth_passed, c.samples_written);
  if (ctx.config.method == Method::kLk)
    s += fmt::format("  surface-id changes {}  sorts {}\n", c.surface_id_changes, c.sorts);
  s += fmt::format("  state traffic: {} B read, {} B written; {} tiles touched\n", c.state_bytes_read(),
                   c.state_bytes_written(), c.tiles_touched);
  for (int b = 0; b < kBuffers; ++b)
    if (run.compression.compressed[size_t(b)]) {
      const BufferCompression& bc = run.compression.buffers[size_t(b)];
      s += fmt::format("  {} compressibility: {} B -> {} B ({:.2f}:1), {} of {} tiles cleared\n", to_string(Buffer(b)),
                       bc.bytes_uncompressed, bc.bytes_compressed,
                       bc.bytes_compressed ? double(bc.bytes_uncompressed) / double(bc.bytes_compressed) : 1.0,
                       bc.tiles_cleared, bc.tiles);
    }
  s += fmt::format("  wall {:.3f} s, {:.1f} M samples/s\n", run.wall_seconds,
                   run.wall_seconds > 0 ? c.samples_tested / run.wall_seconds / 1e6 : 0.0);
  if (run.reference) {
    CompareResult cr = compare_images(run.image, *run.reference);
    s += fmt::format("  vs reference: RMSE {:.3f} (8-bit units), PSNR {:.2f} dB\n", cr.rmse_8bit, cr.psnr_db);
  }
  for (const auto& o : ctx.outputs) s += "  wrote " + o + "\n";
  return s;
}

}  // namespace ropsim
