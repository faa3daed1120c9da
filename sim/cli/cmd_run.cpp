// `ropsim run`: replay a trace or a built-in scene through the functional or
// the cycle model; write images, a JSON report (and a VCD waveform).
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

namespace ropsim {

namespace {

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
Fidelity fidelity_of(const RunOpts& o) {
  const auto f = parse_fidelity(o.fidelity);
  invariant(f.has_value(), "--fidelity is checked against fidelity_names()");
  return *f;
}

/// The sampling flags (a library fixes them when it is built).
constexpr const char* kSamplingFlags[] = {"--sample-units",    "--sample-size",    "--sample-warmup",
                                          "--sample-cooldown", "--sample-warming", "--sample-warming-reach"};
/// The flags that choose a scene input.
constexpr const char* kSceneFlags[] = {"--scene", "--spp", "--width", "--height", "--scene-seed"};

/// A text output staged beside the images (the --stats-interval CSV, the
/// --draw-csv table, a --maps image: text holds any bytes).
struct TextOutput {
  std::string path, text;
};

/// The breakdown's outputs: the per-draw CSV, and per map an EXR and a PNG
/// in the --maps folder (the error against the reference too, when there is
/// one: per-pixel RMSE over R, G, B in 8-bit units).
void add_breakdown_outputs(const RunOpts& o, const RunBreakdown* b, bool with_cycles, const Image& image,
                           const std::optional<Image>& reference, std::vector<TextOutput>& texts,
                           uint32_t dram_listed = 0) {
  if (!b) return;
  if (!o.draw_csv.empty()) texts.push_back(TextOutput{o.draw_csv, draws_csv(*b, with_cycles, dram_listed)});
  if (o.maps.empty()) return;
  const uint32_t w = b->width(), h = b->height();
  auto add = [&](const std::string& name, const std::string& unit, const MapRows& rows, double max) {
    const std::string base = (std::filesystem::path(o.maps) / name).string();
    const auto exr = encode_heat_exr(w, h, rows, base + ".exr");
    const auto png = encode_heat_png(w, h, rows, max, HeatLabels{name, unit}, base + ".png");
    texts.push_back(TextOutput{base + ".exr", std::string(exr.begin(), exr.end())});
    texts.push_back(TextOutput{base + ".png", std::string(png.begin(), png.end())});
  };
  for (size_t i = 0; i < pixel_map_descs().size(); ++i) {
    const PixelMap m = PixelMap(i);
    add(
        pixel_map_descs()[i].name, std::string(pixel_map_descs()[i].unit) + " per pixel",
        [b, m](uint32_t y, float* out) { b->row(m, y, out); }, double(b->max(m)));
  }
  if (reference) {
    std::vector<float> a(size_t(w) * 3), r(a.size());
    auto rows = [&](uint32_t y, float* out) {
      image.row(y, a.data());
      reference->row(y, r.data());
      for (uint32_t x = 0; x < w; ++x) {
        double s = 0;
        for (int c = 0; c < 3; ++c) {
          const double d = double(a[3 * x + c]) - double(r[3 * x + c]);
          s += d * d;
        }
        out[x] = float(std::sqrt(s / 3.0) * 255.0);
      }
    };
    float max = 0;
    std::vector<float> row(w);
    for (uint32_t y = 0; y < h; ++y) {
      rows(y, row.data());
      for (float v : row) max = std::max(max, v);
    }
    add("error", "8-bit units", rows, double(max));
  }
}

/// The cycle model's per-tile maps (--maps; attribution.h): per distributor
/// tile, an EXR with one pixel per tile (so each sums to its report counter)
/// and a screen-sized PNG (each tile's value over its pixels, to lay over the
/// frame).
void add_tile_maps(const RunOpts& o, const CycleRun& run, std::vector<TextOutput>& texts) {
  const Attribution* a = run.tiles.get();
  if (!a || o.maps.empty()) return;
  const uint32_t tx = run.tiles_x, ty = run.tiles_y, tp = run.stats.hw.distributor.tile_pixels;
  const uint32_t w = run.header.width, h = run.header.height;
  for (size_t i = 0; i < tile_map_descs().size(); ++i) {
    const StatDesc& m = tile_map_descs()[i];
    const std::vector<uint64_t>& v = tile_map(*a, i);
    uint64_t max = 0;
    for (uint64_t x : v) max = std::max(max, x);
    const std::string base = (std::filesystem::path(o.maps) / m.name).string();
    const auto exr = encode_heat_exr(
        tx, ty,
        [&](uint32_t y, float* out) {
          for (uint32_t x = 0; x < tx; ++x) out[x] = float(v[size_t(y) * tx + x]);
        },
        base + ".exr");
    const auto png = encode_heat_png(
        w, h,
        [&](uint32_t y, float* out) {
          for (uint32_t x = 0; x < w; ++x) out[x] = float(v[size_t(y / tp) * tx + x / tp]);
        },
        double(max), HeatLabels{m.name, std::string(m.unit) + " per tile"}, base + ".png");
    texts.push_back(TextOutput{base + ".exr", std::string(exr.begin(), exr.end())});
    texts.push_back(TextOutput{base + ".png", std::string(png.begin(), png.end())});
  }
}

/// Writes the images and the report, all or none: every output is staged in
/// its own temporary file first, then all are committed (renamed). A failure
/// while staging leaves nothing; main removes outputs this run created (e.g.
/// a waveform) when it fails. report_text is called after the images are
/// staged, so it can list them. A report to "-" (stdout) is written last.
template <class ReportText>
void write_outputs(ReportContext& ctx, const Image& image, const std::vector<std::string>& outs,
                   const std::string& report, ReportText report_text, const std::vector<TextOutput>& texts = {}) {
  std::vector<std::unique_ptr<OutputFile>> staged;
  for (const auto& p : outs) {
    const std::vector<unsigned char> bytes = encode_image(image, p);
    ensure_parent_dir(p);
    staged.push_back(std::make_unique<OutputFile>(p));
    staged.back()->write(bytes.data(), bytes.size());
    ctx.outputs.push_back(p);
  }
  for (const auto& t : texts) {
    ensure_parent_dir(t.path);
    staged.push_back(std::make_unique<OutputFile>(t.path));
    staged.back()->write(t.text);
    ctx.outputs.push_back(t.path);
  }
  std::unique_ptr<OutputFile> rep;
  if (!report.empty()) {
    ensure_parent_dir(report);
    OutputFile::Options o;
    o.allow_stdout = true;
    rep = std::make_unique<OutputFile>(report, o);
    if (!rep->to_stdout()) ctx.outputs.push_back(report);
    const std::string text = report_text() + "\n";
    if (!rep->to_stdout()) rep->write(text);
    for (auto& f : staged) f->commit();
    if (rep->to_stdout()) rep->write(text);
    rep->commit();
    return;
  }
  for (auto& f : staged) f->commit();
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

/// The GTKWave save file beside the waveform: its name with .gtkw for its extension.
std::string gtkw_path(const std::string& vcd) {
  std::filesystem::path p(vcd);
  if (p.extension() == ".gtkw") return vcd + ".gtkw";
  return p.replace_extension(".gtkw").string();
}

/// The samples per pixel of an input: a scene's flag, a trace's header.
int input_spp(const RunOpts& o, const InputSpec& in) {
  if (!in.from_trace()) return o.spp;
  return int(TraceReader(in.trace_path).header().spp);
}

/// The default outputs' name, out/run/BASE.{png,exr,json} (docs/outputs.md
/// "Default names"): the input replayed (a trace file's stem, or a scene's
/// name with the parameters that change it), its spp and the method, then
/// what else makes two runs' results differ: the slab's k and b, the
/// fidelity and the design's digest, or a functional run's non-default
/// numerics.
std::string default_output_base(const RunOpts& o, const InputSpec& in, int spp, const GoldenConfig& cfg,
                                const HwConfig& hw) {
  std::string base;
  if (in.from_trace()) {
    base = std::filesystem::path(in.trace_path).stem().string();
  } else {
    const SceneParams& sp = in.scene;
    base = sp.name;
    if (sp.width || sp.height) {
      uint32_t w = sp.width, h = sp.height;
      for (const auto& c : scene_catalog())
        if (c.name == sp.name) {
          if (!w) w = c.width;
          if (!h) h = c.height;
        }
      base += fmt::format("-{}x{}", w, h);
    }
    if (sp.seed != SceneParams{}.seed) base += fmt::format("-seed{}", sp.seed);
  }
  base = fmt::format("out/run/{}-{}-{}spp", base, to_string(cfg.method), spp);
  if (in.repeat > 1) base += fmt::format("-x{}", in.repeat);
  if (cfg.method == Method::kSlab) base += fmt::format("-k{}b{}", cfg.slab_layers, cfg.slab_bits);
  // Distinct designs never share a name: a timed run adds a digest of the
  // resolved design (numerics included), a functional run its numerics when
  // they are not the defaults.
  const Numerics& n = cfg.numerics;
  if (const Fidelity f = fidelity_of(o); is_timed(f))
    base += fmt::format("-{}-hw{}", to_string(f), hw_digest_hex(hw));
  else if (n.hash_bits != Numerics{}.hash_bits || n.alpha_bits != Numerics{}.alpha_bits ||
           n.surface_id_bits != Numerics{}.surface_id_bits)
    base += fmt::format("-h{}a{}s{}", n.hash_bits, n.alpha_bits, n.surface_id_bits);
  return base;
}

/// The --maps folder's files a run writes (add_breakdown_outputs,
/// add_tile_maps): per map an EXR and a PNG.
std::vector<std::string> map_files(const RunOpts& o, bool cycle) {
  std::vector<std::string> names;
  for (const auto& d : pixel_map_descs()) names.push_back(d.name);
  if (o.vs_reference) names.push_back("error");
  if (cycle)
    for (const auto& d : tile_map_descs()) names.push_back(d.name);
  std::vector<std::string> files;
  for (const auto& n : names)
    for (const char* ext : {".exr", ".png"}) files.push_back((std::filesystem::path(o.maps) / n).string() + ext);
  return files;
}

/// Refuses, before any work, two outputs of the run that are one file (the
/// same name, a link, an implied file) and an output that is an input.
void check_outputs(const RunOpts& o, const std::vector<std::string>& outs, const std::string& report, bool cycle) {
  const bool defaults = o.outs.empty() && o.report.empty();
  OutputPlan plan;
  plan.input("--trace", o.trace);
  plan.input("--livepoints", o.livepoints);
  plan.input("--hw", o.hw);
  for (const auto& p : outs) plan.output(defaults ? "the default image" : "--out", p);
  plan.output(defaults ? "the default report" : "--report", report);
  plan.output("--vcd", o.vcd);
  if (!o.vcd.empty()) plan.output("--vcd's GTKWave save file", gtkw_path(o.vcd));
  plan.output("--stats-csv", o.stats_csv);
  plan.output("--draw-csv", o.draw_csv);
  if (!o.maps.empty()) {
    plan.output("--maps", o.maps);
    for (const auto& f : map_files(o, cycle)) plan.output("--maps", f);
  }
  plan.check();
}

/// Refuses, before any work, a design whose model does not fit in
/// --memory-limit (memory_estimate.h; the model charges it again as it is
/// built). copies: the pipelines alive at once (sampled workers).
void check_design_memory(const InputSpec& in, const GoldenConfig& cfg, const HwConfig& hw, MemoryModel model,
                         uint32_t copies = 1) {
  const TraceHeader h = open_fragments(in)->header();
  check_model_memory(hw, estimate_memory(hw, MemoryShape{h.width, h.height, h.spp, cfg.method, copies}, model));
}

int cmd_run_cycle(const RunOpts& o, const InputSpec& in, const GoldenConfig& cfg, const HwConfig& hw,
                  uint64_t vcd_first, uint64_t vcd_last, const std::vector<std::string>& outs,
                  const std::string& report, const std::string& cmdline) {
  CycleOptions opt;
  opt.vcd_first = vcd_first;
  opt.vcd_last = vcd_last;
  opt.lockstep = o.lockstep;
  opt.stats_interval = o.stats_interval;
  opt.breakdown = o.breakdown();
  auto progress = std::make_shared<Progress>("cycle model", "fragments");
  if (progress->shown()) opt.progress = [progress](uint64_t n, double consumed) { progress->update(consumed, n); };
  if (!o.vcd.empty()) {
    ensure_parent_dir(o.vcd);
    opt.vcd_path = o.vcd;
    opt.gtkw_path = gtkw_path(o.vcd);
  }
  std::optional<Image> reference;
  if (o.vs_reference) {
    check_design_memory(in, cfg, hw, MemoryModel::kCycle);  // before the reference's run
    GoldenConfig rc = cfg;
    rc.method = Method::kReference;
    reference = run_functional(in, rc).image;
  }
  RunResult result(run_cycle(in, cfg, hw, opt));
  result.set_reference(std::move(reference));
  const CycleRun& run = *result.cycle();
  progress->update(1.0, run.counters.fragments);
  progress->finish();
  ReportContext ctx{cmdline, in, cfg, {}, {}, frame_of(in)};
  if (!o.vcd.empty()) {
    ctx.outputs.push_back(o.vcd);
    ctx.outputs.push_back(opt.gtkw_path);
  }
  std::vector<TextOutput> texts;
  if (run.intervals) texts.push_back(TextOutput{o.stats_csv, interval_csv(run)});
  add_breakdown_outputs(o, run.breakdown.get(), true, run.image, result.reference(), texts, run.stats.listed);
  add_tile_maps(o, run, texts);
  write_outputs(
      ctx, run.image, outs, report, [&] { return run_report(ctx, result).dump(2); }, texts);
  if (!o.quiet && report != "-") std::fputs(run_summary(ctx, result).c_str(), stdout);
  return 0;
}

/// The library of `--livepoints LIB`, read and checked against the flags
/// that name an input or a method (a library fixes its input, its sampling,
/// its method and numerics); run_cfg gets the method it serves.
LivePoints read_library(const RunOpts& o, CLI::App& sub, const InputSpec& in, const GoldenConfig& cfg,
                        const HwConfig& hw, GoldenConfig& run_cfg) {
  for (const char* f : kSamplingFlags)
    if (sub.count(f))
      throw UserError(std::string(f) +
                      " does not apply with --livepoints: the library fixes the sampling (give it to "
                      "`ropsim livepoints`)");
  LivePoints lib = read_livepoints(o.livepoints);
  // The input, when named, must be the library's; unnamed, it is.
  bool scene_named = false;
  for (const char* f : kSceneFlags) scene_named = scene_named || sub.count(f) > 0;
  if (in.from_trace() || scene_named) {
    InputSpec named = in;
    named.repeat = lib.input.spec.repeat;
    check_library_input(lib, o.livepoints, named);
  }
  // The method: the library's, unless a flag names it (then they must agree).
  run_cfg = lib.method;
  if (sub.count("--method")) run_cfg.method = cfg.method;
  if (sub.count("--seed")) run_cfg.seed = cfg.seed;
  if (sub.count("--slab-layers")) run_cfg.slab_layers = cfg.slab_layers;
  if (sub.count("--slab-bits")) run_cfg.slab_bits = cfg.slab_bits;
  if (sub.count("--enderton-selection")) run_cfg.enderton_selection = cfg.enderton_selection;
  run_cfg.numerics = hw.numerics;  // the design's: a library serves designs of its numerics
  check_library_method(lib, o.livepoints, run_cfg);
  return lib;
}

/// A sampled run: on the library read (library non-null, with the method
/// run_cfg it serves), else on live-points recorded from in now.
int cmd_run_sampled(const RunOpts& o, const InputSpec& in, const GoldenConfig& run_cfg, const HwConfig& hw,
                    LivePoints* library, std::chrono::steady_clock::time_point t0, const std::vector<std::string>& outs,
                    const std::string& report, const std::string& cmdline) {
  LibrarySource from;
  LivePoints recorded;
  if (library)
    from.path = o.livepoints;
  else {
    // Before the library is recorded: the workers' pipelines must fit.
    const int jobs = o.jobs > 0 ? o.jobs : available_cores();
    check_design_memory(in, run_cfg, hw, MemoryModel::kCycle,
                        uint32_t(std::max<uint64_t>(1, std::min<uint64_t>(uint64_t(jobs), o.sampling.units))));
    recorded = record_livepoints(in, run_cfg, o.sampling);
  }
  const LivePoints& lib = library ? *library : recorded;
  from.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  RunRequest req;
  req.fidelity = Fidelity::kSampled;
  req.hw = hw;
  req.library = &lib;
  req.from = from;
  req.jobs = o.jobs > 0 ? o.jobs : available_cores();
  req.started = t0;
  const RunResult result = run_fidelity(req);
  // (a library's frame statistics are not kept: its trace may be elsewhere)
  ReportContext ctx{cmdline, library ? lib.input.spec : in, run_cfg, {}, {}, library ? std::nullopt : frame_of(in)};
  write_outputs(ctx, lib.image, outs, report, [&] { return run_report(ctx, result).dump(2); });
  if (!o.quiet && report != "-") std::fputs(run_summary(ctx, result).c_str(), stdout);
  return 0;
}

int cmd_run_approximate(const InputSpec& in, const GoldenConfig& cfg, const HwConfig& hw, const RunOpts& o,
                        const std::vector<std::string>& outs, const std::string& report, const std::string& cmdline) {
  const RunResult result(run_approximate(in, cfg, hw));
  ReportContext ctx{cmdline, in, cfg, {}, {}, frame_of(in)};
  write_outputs(ctx, result.image(), outs, report, [&] { return run_report(ctx, result).dump(2); });
  if (!o.quiet && report != "-") std::fputs(run_summary(ctx, result).c_str(), stdout);
  return 0;
}

int cmd_run(const RunOpts& o, CLI::App& sub, const std::string& cmdline) {
  set_progress_flags(o.quiet, o.progress);
  const Fidelity fidelity = fidelity_of(o);
  const bool cycle = fidelity == Fidelity::kCycle, sampled = fidelity == Fidelity::kSampled;
  const bool approximate = fidelity == Fidelity::kApproximate;
  if (!sampled) {
    for (const char* f : kSamplingFlags)
      if (sub.count(f)) throw UserError(std::string(f) + " applies to --fidelity sampled");
    for (const char* f : {"--livepoints", "--jobs"})
      if (sub.count(f)) throw UserError(std::string(f) + " applies to --fidelity sampled");
  }
  if (approximate)
    for (const char* f : {"--vcd", "--vcd-window", "--lockstep", "--stats-interval", "--stats-csv", "--vs-reference",
                          "--per-draw", "--draw-csv", "--maps"})
      if (sub.count(f)) throw UserError(std::string(f) + " does not apply to --fidelity approximate");
  if (sampled) {
    for (const char* f : {"--vcd", "--vcd-window", "--lockstep", "--stats-interval", "--stats-csv", "--vs-reference",
                          "--repeat", "--per-draw", "--draw-csv", "--maps"})
      if (sub.count(f)) throw UserError(std::string(f) + " does not apply to --fidelity sampled");
  }
  if ((cycle || sampled || approximate) && o.compressibility)
    throw UserError(
        "--compressibility applies to --fidelity functional (a timing fidelity reports the compressed "
        "traffic of the design it runs)");
  if (!cycle && !sampled && !approximate) {
    for (const char* f : {"--vcd", "--vcd-window", "--lockstep", "--stats-interval", "--stats-csv"})
      if (sub.count(f)) throw UserError(std::string(f) + " applies to --fidelity cycle");
    // A functional run takes only the design's numerics, blend-target
    // formats and compression format (the rest is timing).
    for (const auto& a : o.hw_sets)
      if (a.rfind("numerics.", 0) != 0 && a.rfind("blend.transmittance_format=", 0) != 0 &&
          a.rfind("blend.accum_format=", 0) != 0 && a.rfind("compression.", 0) != 0)
        throw UserError("--hw-set " + a +
                        " applies to --fidelity cycle (a functional run takes only the numerics.*, "
                        "blend.*_format and compression.* keys of a design)");
  }
  if (sub.count("--vcd-window") && o.vcd.empty()) throw UserError("--vcd-window needs --vcd FILE");
  if (sub.count("--stats-interval") != sub.count("--stats-csv"))
    throw UserError("--stats-interval N and --stats-csv FILE go together");
  if (o.stats_csv == "-") throw UserError("--stats-csv -: give a file name");
  // The design (a functional run uses only its numerics); the run's numerics
  // flags, when given, override the design's.
  HwConfig hw = resolve_design(o, sub);
  if (o.compressibility && !hw.compression.any())
    throw UserError("--compressibility: design " + hw.name + " compresses no surface ([compression] depth and color)");
  uint64_t vcd_first = 0, vcd_last = ~uint64_t{0};
  if (cycle) {
    if (!o.vcd_window.empty()) {
      const auto colon = o.vcd_window.find(':');
      char* end = nullptr;
      bool ok = colon != std::string::npos && colon > 0 && colon + 1 < o.vcd_window.size();
      if (ok) {
        vcd_first = std::strtoull(o.vcd_window.c_str(), &end, 10);
        ok = end == o.vcd_window.c_str() + colon;
      }
      if (ok) {
        vcd_last = std::strtoull(o.vcd_window.c_str() + colon + 1, &end, 10);
        ok = *end == '\0' && vcd_first <= vcd_last && o.vcd_window[0] != '-' && o.vcd_window[colon + 1] != '-';
      }
      if (!ok) throw UserError("--vcd-window " + o.vcd_window + ": expected FIRST:LAST cycles with FIRST <= LAST");
    }
  }
  if (o.vcd == "-") throw UserError("--vcd -: the waveform cannot go to standard output; give a file name");
  const InputSpec in = resolve_input(o, sub);
  const GoldenConfig cfg = resolve_method(o, hw);
  std::vector<std::string> outs = o.outs;
  std::string report = o.report;
  for (const auto& p : outs) {  // fail before the run, not after
    auto ext = std::filesystem::path(p).extension().string();
    if (ext != ".png" && ext != ".exr") throw UserError("--out " + p + ": use a .png or .exr file name");
  }
  // A sampled run on a library replays the library's input with its method:
  // read it first, so that the outputs are named after what runs.
  const auto t0 = std::chrono::steady_clock::now();
  std::optional<LivePoints> library;
  GoldenConfig run_cfg = cfg;
  if (sampled && !o.livepoints.empty()) library = read_library(o, sub, in, cfg, hw, run_cfg);
  if (outs.empty() && report.empty()) {
    const std::string base = library
                                 ? default_output_base(o, library->input.spec, int(library->header.spp), run_cfg, hw)
                                 : default_output_base(o, in, input_spp(o, in), run_cfg, hw);
    outs = {base + ".png", base + ".exr"};
    report = base + ".json";
  }
  check_outputs(o, outs, report, cycle);
  if (cycle) {
    if (cfg.method == Method::kReference)
      throw UserError("--method reference has no ROP pipeline: use --fidelity functional");
    return cmd_run_cycle(o, in, cfg, hw, vcd_first, vcd_last, outs, report, cmdline);
  }
  if (sampled) return cmd_run_sampled(o, in, run_cfg, hw, library ? &*library : nullptr, t0, outs, report, cmdline);
  if (approximate) return cmd_run_approximate(in, cfg, hw, o, outs, report, cmdline);
  const RunResult result(run_functional(in, cfg, o.vs_reference, 0, o.breakdown()));
  const FunctionalRun& run = *result.functional();
  ReportContext ctx{cmdline, in, cfg, {}, {}, frame_of(in)};
  ctx.design = rtl_design_of(hw);  // the silicon cost: the --hw design (or the built-in one)
  std::vector<TextOutput> texts;
  add_breakdown_outputs(o, run.breakdown.get(), false, run.image, run.reference, texts);
  write_outputs(
      ctx, run.image, outs, report, [&] { return run_report(ctx, result).dump(2); }, texts);
  if (!o.quiet && report != "-") std::fputs(run_summary(ctx, result).c_str(), stdout);
  return 0;
}

}  // namespace

namespace {

/// `ropsim livepoints`: one functional pass recording the live-points of a
/// sampled simulation, written to a library every design of a sweep reuses.
int cmd_livepoints(const RunOpts& o, CLI::App& sub) {
  set_progress_flags(o.quiet, o.progress);
  for (const auto& a : o.hw_sets)
    if (a.rfind("numerics.", 0) != 0)
      throw UserError("--hw-set " + a +
                      ": a live-point library takes only the numerics.* keys of a design (the rest "
                      "is timing, chosen per run)");
  const HwConfig hw = resolve_design(o, sub);
  const InputSpec in = resolve_input(o, sub);
  const GoldenConfig cfg = resolve_method(o, hw);
  OutputPlan plan;
  plan.input("TRACE", o.trace);
  plan.input("--hw", o.hw);
  plan.output("-o", o.library_out);
  plan.check();
  const auto t0 = std::chrono::steady_clock::now();
  const LivePoints lib = record_livepoints(in, cfg, o.sampling);
  const double rec = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  write_livepoints(o.library_out, lib);
  const double all = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!o.quiet) {
    uint64_t detailed = 0;
    for (const LivePoint& p : lib.points) detailed += p.fragments.size();
    std::error_code ec;
    const auto bytes = std::filesystem::file_size(o.library_out, ec);
    std::fputs(
        fmt::format("ropsim: {} | method {} | {}x{} @ {} spp\n"
                    "  {} units of {} fragments ({} in detail of {}); recorded in {:.2f} s, written in {:.2f} s\n"
                    "  wrote {} ({})\n",
                    in.describe(), to_string(cfg.method), lib.header.width, lib.header.height, lib.header.spp,
                    lib.points.size(), lib.params.unit_fragments, detailed, lib.fragments, rec, all - rec,
                    o.library_out, ec ? std::string("?") : format_bytes(uint64_t(bytes)))
            .c_str(),
        stdout);
  }
  return 0;
}

}  // namespace

namespace {

/// The options a run and a live-point library share: the scene input, the
/// method and its numerics.
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

}  // namespace

VerbRunner add_run_command(CLI::App& app, const std::string& command_line) {
  auto ro = std::make_shared<RunOpts>();
  CLI::App* run = app.add_subcommand(
      "run", "Replay a trace or a built-in scene through the ROP model; write images and a JSON report");
  auto* opt_trace =
      run->add_option("--trace", ro->trace, "Fragment trace file (ropsim trace v1)")->check(CLI::ExistingFile);
  add_input_and_method_options(run, ro.get(), opt_trace);
  run->add_option("-o,--out", ro->outs,
                  "Output image(s): .png (sRGB 8-bit) or .exr (linear float); repeatable. Missing folders are made; "
                  "no two outputs may be one file (docs/outputs.md; default: out/run/ named after the input, "
                  "method and design)");
  run->add_option("--report", ro->report, "JSON report file (- for standard output, then no summary is printed)");
  run->add_option(
         "--fidelity", ro->fidelity,
         "functional (the golden model, default), cycle (the cycle-approximate SystemC pipeline), sampled "
         "(the pipeline on sampling units of the input, with 95 % intervals) or approximate (the analytical timing "
         "model: bounds from a tag-only cache and DRAM simulation)")
      ->check(CLI::IsMember(fidelity_names()));
  add_sampling_options(run, ro.get());
  run->add_option("--livepoints", ro->livepoints,
                  "sampled: read the live-points from this library (ropsim livepoints) instead of recording them: no "
                  "functional pass; refused for another input, method or numerics")
      ->check(CLI::ExistingFile)
      ->type_name("LIB");
  run->add_option("-j,--jobs", ro->jobs, "sampled: worker processes simulating the units (default: every core)")
      ->check(in_range(1, 1024));
  add_design_options(run, ro.get());
  run->add_option("--vcd", ro->vcd,
                  "cycle: write a VCD waveform in clock cycles (with a clock): unit activities by name, FIFO "
                  "occupancies, DRAM channels; one scope per ROP; and beside it FILE.gtkw, a GTKWave save file "
                  "showing them");
  run->add_option("--vcd-window", ro->vcd_window,
                  "cycle: cycles FIRST:LAST (both included) the waveform shows (default: the whole run)");
  run->add_flag("--lockstep", ro->lockstep,
                "cycle: run every unit in lockstep with SystemC time, none decoupled (same results, slower; "
                "for checking the decoupling)");
  run->add_option("--stats-interval", ro->stats_interval,
                  "cycle: also write the run's statistics every N cycles (--stats-csv; docs/reports.md)")
      ->check(in_range(uint64_t{1}))
      ->type_name("N");
  run->add_option("--stats-csv", ro->stats_csv, "cycle: the CSV file of --stats-interval")->type_name("FILE");
  run->add_option("--repeat", ro->repeat, "Draw the input this many times into one frame (default 1)")
      ->check(in_range(1u, kMaxRepeat));
  run->add_flag("--compressibility", ro->compressibility,
                "functional: report the final surfaces' compressed sizes under the design's [compression] (the "
                "store keeps each depth's plane key, 8 bytes a sample)");
  run->add_flag("--vs-reference", ro->vs_reference,
                "Also run the A-buffer reference on the same stream and report the RMSE");
  run->add_flag("--per-draw", ro->per_draw,
                "Split the counters by the trace's draw ids: the report's draws[] (functional, cycle: also the cycles "
                "and the DRAM bytes per buffer attributed to each draw)");
  run->add_option("--draw-csv", ro->draw_csv, "The per-draw table as CSV (implies --per-draw)")->type_name("FILE");
  run->add_option("--maps", ro->maps,
                  "Write per-pixel heat maps into DIR, each as EXR (values) and PNG (colour scale): fragments (depth "
                  "complexity), samples tested, depth-passed and written, surface-id changes, and with --vs-reference "
                  "the error; cycle: also per distributor tile the cycles, the units' busy and stall cycles and the "
                  "cache misses")
      ->type_name("DIR");
  run->add_flag("--quiet", ro->quiet, "Print nothing on success");
  run->add_flag("--progress", ro->progress,
                "Show progress (share of the input consumed, rate, ETA) even when stderr is not a terminal: a line "
                "every 5 s, for logs");
  run->footer(examples(
      {"ropsim run --trace cloth.trace --method lk -o lk.png -o lk.exr --report lk.json",
       "ropsim run --trace cloth.trace --method reference -o reference.exr   # the A-buffer ground truth",
       "ropsim run --fidelity cycle --hw configs/narrow.toml --trace cloth.trace   # cycles, DRAM, the bottleneck"}));
  return [ro, run, command_line]() { return run->parsed() ? cmd_run(*ro, *run, command_line) : -1; };
}

VerbRunner add_livepoints_command(CLI::App& app) {
  auto ro = std::make_shared<RunOpts>();
  CLI::App* lp = app.add_subcommand(
      "livepoints",
      "Record the live-points of a sampled simulation in one functional pass and write them to a library, which "
      "`run --fidelity sampled --livepoints LIB` reuses for every design (docs/livepoints.md)");
  auto* opt_trace = lp->add_option("trace", ro->trace, "Fragment trace file (or --scene NAME)")
                        ->check(CLI::ExistingFile)
                        ->type_name("TRACE");
  add_input_and_method_options(lp, ro.get(), opt_trace);
  add_sampling_options(lp, ro.get());
  lp->add_option("--hw", ro->hw, "Hardware design file: only its [numerics] (a library serves designs of its numerics)")
      ->check(CLI::ExistingFile);
  lp->add_option("--hw-set", ro->hw_sets, "Override one numerics.* key of the design, section.key=value; repeatable");
  lp->add_option("-o,--out", ro->library_out, "The library file to write")->required()->type_name("LIB");
  lp->add_flag("--quiet", ro->quiet, "Print nothing on success");
  lp->add_flag("--progress", ro->progress,
               "Show progress even when stderr is not a terminal: a line every 5 s, for logs");
  lp->footer(examples({"ropsim livepoints cloth.trace -o cloth.rlp",
                       "ropsim run --fidelity sampled --livepoints cloth.rlp --hw configs/wide.toml -j 2   # then "
                       "any design from it"}));
  return [ro, lp]() { return lp->parsed() ? cmd_livepoints(*ro, *lp) : -1; };
}

}  // namespace ropsim
