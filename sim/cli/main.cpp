// ropsim: command-line entry point. Thin: parses flags, calls the driver,
// prints the summary. Every user error is one line and a non-zero exit.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <cstdio>
#include <unistd.h>
#include <filesystem>
#include <chrono>
#include <iostream>
#include <optional>

#include "cycle_report.h"
#include "cycle_run.h"
#include "cmd_capture.h"
#include "driver.h"
#include "hw_config.h"
#include "image_io.h"
#include "report.h"
#include "scenes.h"
#include "tile_map.h"
#include "trace.h"
#include "vectors.h"

using namespace ropsim;

namespace {

struct UserError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

std::string join(const std::vector<std::string>& v, const char* sep = ", ") {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : sep) + x;
  return s;
}

std::vector<std::string> scene_names() {
  std::vector<std::string> v;
  for (const auto& s : scene_catalog()) v.push_back(s.name);
  return v;
}

void ensure_parent_dir(const std::string& path) {
  std::filesystem::path p(path);
  if (p.has_parent_path()) std::filesystem::create_directories(p.parent_path());
}

struct RunOpts {
  std::string trace, scene = "cloth", method = "lk", fidelity = "functional", report;
  std::string hw, vcd, vcd_window;
  std::vector<std::string> hw_sets;
  uint32_t repeat = 1;
  std::vector<std::string> outs;
  int spp = 16;
  uint32_t width = 0, height = 0;
  uint64_t seed = 1, scene_seed = 1;
  Numerics num;
  bool vs_reference = false, quiet = false, lockstep = false;
};

/// Writes the images and the report, all or none: a failure removes what
/// this run already wrote (ctx.outputs may already hold e.g. a waveform).
/// report_text is called after the images, so it can list them.
template <class ReportText>
void write_outputs(ReportContext& ctx, const Image& image, const std::vector<std::string>& outs,
                   const std::string& report, ReportText report_text) {
  try {
    for (const auto& p : outs) {
      ensure_parent_dir(p);
      ctx.outputs.push_back(p);
      write_image(image, p);
    }
    if (!report.empty()) {
      ensure_parent_dir(report);
      ctx.outputs.push_back(report);
      write_text_file_atomic(report, report_text() + "\n");
    }
  } catch (...) {
    for (const auto& p : ctx.outputs) std::remove(p.c_str());
    throw;
  }
}

int cmd_run_cycle(const RunOpts& o, const InputSpec& in, const GoldenConfig& cfg, const HwConfig& hw, uint64_t vcd_first,
                  uint64_t vcd_last, const std::vector<std::string>& outs, const std::string& report,
                  const std::string& cmdline) {
  CycleOptions opt;
  opt.vcd_first = vcd_first;
  opt.vcd_last = vcd_last;
  opt.lockstep = o.lockstep;
  const bool tty = !o.quiet && isatty(fileno(stderr));
  const auto t0 = std::chrono::steady_clock::now();
  if (tty)
    opt.progress = [t0](uint64_t n) {
      const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      std::fprintf(stderr, "\r  cycle model: %llu fragments, %.2f M/s ", (unsigned long long)n, s > 0 ? n / s / 1e6 : 0.0);
    };
  if (!o.vcd.empty()) {
    ensure_parent_dir(o.vcd);
    opt.vcd_path = o.vcd;
  }
  std::optional<Image> reference;
  if (o.vs_reference) {
    GoldenConfig rc = cfg;
    rc.method = Method::kReference;
    reference = run_functional(in, rc).image;
  }
  CycleRun run = run_cycle(in, cfg, hw, opt);
  if (tty) std::fputs("\n", stderr);
  ReportContext ctx{cmdline, in, cfg, {}};
  if (!o.vcd.empty()) ctx.outputs.push_back(o.vcd);
  write_outputs(ctx, run.image, outs, report, [&] { return cycle_report(ctx, run, reference).dump(2); });
  if (!o.quiet) std::fputs(cycle_summary(ctx, run, reference).c_str(), stdout);
  return 0;
}

int cmd_run(const RunOpts& o, CLI::App& sub, const std::string& cmdline) {
  const bool cycle = o.fidelity == "cycle";
  if (!cycle)
    for (const char* f : {"--hw", "--hw-set", "--vcd", "--vcd-window", "--lockstep"})
      if (sub.count(f)) throw UserError(std::string(f) + " applies to --fidelity cycle");
  if (sub.count("--vcd-window") && o.vcd.empty()) throw UserError("--vcd-window needs --vcd FILE");
  HwConfig hw;
  uint64_t vcd_first = 0, vcd_last = ~uint64_t{0};
  if (cycle) {
    if (!o.hw.empty()) hw = load_hw_config(o.hw);
    for (const auto& a : o.hw_sets) apply_hw_override(hw, a);
    if (!o.hw_sets.empty()) hw.name += " with --hw-set";
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
  InputSpec in;
  in.repeat = o.repeat;
  if (!o.trace.empty()) {
    in.trace_path = o.trace;
    for (const char* f : {"--scene", "--spp", "--width", "--height", "--scene-seed"})
      if (sub.count(f)) throw UserError(std::string(f) + " applies to --scene, not --trace");
  } else {
    in.scene.name = o.scene;
    in.scene.spp = o.spp;
    in.scene.width = o.width;
    in.scene.height = o.height;
    in.scene.seed = o.scene_seed;
  }
  GoldenConfig cfg;
  parse_method(o.method, cfg.method);
  cfg.numerics = o.num;
  cfg.seed = o.seed;
  std::vector<std::string> outs = o.outs;
  std::string report = o.report;
  if (outs.empty() && report.empty()) {
    const std::string stem = in.from_trace() ? std::filesystem::path(o.trace).stem().string() : o.scene;
    // A trace's spp is in its header, which is only read by the run: name by stem.
    std::string base = in.from_trace() ? fmt::format("out/run/{}-{}", stem, o.method)
                                       : fmt::format("out/run/{}-{}-{}spp", stem, o.method, o.spp);
    if (cycle) base += "-cycle";
    outs = {base + ".png", base + ".exr"};
    report = base + ".json";
  }
  for (const auto& p : outs) {  // fail before the run, not after
    auto ext = std::filesystem::path(p).extension().string();
    if (ext != ".png" && ext != ".exr") throw UserError("--out " + p + ": use a .png or .exr file name");
  }
  if (cycle) {
    if (cfg.method == Method::kReference)
      throw UserError("--method reference has no ROP pipeline: use --fidelity functional");
    return cmd_run_cycle(o, in, cfg, hw, vcd_first, vcd_last, outs, report, cmdline);
  }
  FunctionalRun run = run_functional(in, cfg, o.vs_reference);
  ReportContext ctx{cmdline, in, cfg, {}};
  write_outputs(ctx, run.image, outs, report, [&] { return functional_report(ctx, run).dump(2); });
  if (!o.quiet) std::fputs(functional_summary(ctx, run).c_str(), stdout);
  return 0;
}

int cmd_trace_info(const std::string& path, bool validate_only) {
  TraceReader r(path);
  Fragment f;
  uint64_t covered = 0;
  uint32_t max_draw = 0;
  // Depth complexity: fragments per touched pixel, in sparse 8x8 tiles.
  struct Counts { std::array<uint32_t, 64> n{}; };
  TileMap<Counts> counts(r.header().width, r.header().height);
  while (r.next(f)) {
    covered += __builtin_popcountll(f.coverage);
    max_draw = std::max(max_draw, f.draw_id);
    if (!validate_only)
      ++counts.get(f.x, f.y, [](uint32_t, uint32_t) { return std::make_unique<Counts>(); }).n[(f.y & 7u) * 8 + (f.x & 7u)];
  }
  const uint64_t n = r.records_read();
  if (validate_only) {
    fmt::print("{}: valid, {} fragments\n", path, n);
    return 0;
  }
  const auto& h = r.header();
  const auto file_bytes = std::filesystem::file_size(path);
  fmt::print("{}\n  scene {}  {}x{}  {} spp\n  depth {}  colour {}  compression {}\n", path, h.scene_name, h.width,
             h.height, h.spp, to_string(h.depth_mode), to_string(h.color_format), to_string(h.compression));
  fmt::print("  fragments {}  covered samples {} ({:.2f} per fragment)  draws {}\n", n, covered,
             n ? double(covered) / n : 0.0, n ? max_draw + 1 : 0);
  fmt::print("  bytes: file {}, records {} ({:.2f} per fragment uncompressed, {:.2f} on disk)\n", file_bytes,
             r.payload_bytes(), n ? double(r.payload_bytes()) / n : 0.0, n ? double(file_bytes) / n : 0.0);
  std::array<uint64_t, 17> hist{};
  uint64_t touched = 0, max_n = 0;
  counts.for_each([&](uint32_t, uint32_t, const Counts& c) {
    for (uint32_t k : c.n) {
      if (!k) continue;
      ++touched;
      ++hist[std::min<uint32_t>(k, 16)];
      max_n = std::max<uint64_t>(max_n, k);
    }
  });
  fmt::print("  pixels touched {} ({:.1f}% of the screen), fragments per touched pixel: mean {:.2f}, max {}\n", touched,
             100.0 * touched / (double(h.width) * h.height), touched ? double(n) / touched : 0.0, max_n);
  std::string hs;
  for (int k = 1; k <= 16; ++k)
    if (hist[k]) hs += fmt::format(" {}{}:{:.1f}%", k, k == 16 ? "+" : "", 100.0 * hist[k] / touched);
  fmt::print("  depth complexity histogram:{}\n", hs);
  return 0;
}

int cmd_trace_dump(const std::string& path, uint64_t limit) {
  TraceReader r(path);
  std::cout << header_to_json(r.header()) << '\n';
  Fragment f;
  uint64_t i = 0;
  while (i < limit && r.next(f)) std::cout << fragment_to_json(r.header(), f, i++) << '\n';
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ropsim: a simulator of a GPU ROP for stratified stochastic transparency (Laine & Karras 2011)"};
  app.require_subcommand(1);
  // Every user error is one line: CLI11's default adds a second "Run with --help" line.
  app.failure_message([](const CLI::App*, const CLI::Error& e) {
    return "ropsim: error: " + std::string(e.what()) + " (see --help)\n";
  });
  std::string cmdline;
  for (int i = 0; i < argc; ++i) cmdline += (i ? " " : "") + std::string(argv[i]);

  // run
  RunOpts ro;
  CLI::App* run = app.add_subcommand("run", "Replay a trace or a built-in scene through the ROP model; write images and a JSON report");
  auto* opt_trace = run->add_option("--trace", ro.trace, "Fragment trace file (ropsim trace v1)")->check(CLI::ExistingFile);
  run->add_option("--scene", ro.scene, "Built-in scene (default cloth): " + join(scene_names()))
      ->check(CLI::IsMember(scene_names()))->excludes(opt_trace);
  run->add_option("--method", ro.method, "Method: " + join(method_names()) + " (default lk)")->check(CLI::IsMember(method_names()));
  run->add_option("--spp", ro.spp, "Samples per pixel for --scene: 1, 2, 4, 8, 16, 32 or 64 (default 16)")
      ->check(CLI::IsMember({1, 2, 4, 8, 16, 32, 64}));
  run->add_option("--width", ro.width, "Scene width in pixels (default: the scene's)")->check(CLI::Range(1u, kMaxScreenSide));
  run->add_option("--height", ro.height, "Scene height in pixels (default: the scene's)")->check(CLI::Range(1u, kMaxScreenSide));
  run->add_option("--scene-seed", ro.scene_seed, "Seed of the scene generator (default 1)");
  run->add_option("--seed", ro.seed, "Seed of the methods' hash-based random numbers (default 1)");
  run->add_option("--hash-bits", ro.num.hash_bits, "Alpha-reference hash datapath width, bits (8..32, default 32)")->check(CLI::Range(8, 32));
  run->add_option("--alpha-bits", ro.num.alpha_bits, "Opacity fixed-point precision, bits (1..32, default 32)")->check(CLI::Range(1, 32));
  run->add_option("--surface-id-bits", ro.num.surface_id_bits, "Surface id register width, bits (1..32, default 32)")->check(CLI::Range(1, 32));
  run->add_option("--out", ro.outs, "Output image(s): .png (sRGB 8-bit) or .exr (linear float); repeatable");
  run->add_option("--report", ro.report, "JSON report file");
  run->add_option("--fidelity", ro.fidelity,
                  "functional (the golden model, default) or cycle (the cycle-approximate SystemC pipeline)")
      ->check(CLI::IsMember({"functional", "cycle"}));
  run->add_option("--hw", ro.hw, "cycle: hardware config file (TOML, docs/config.md; default: built-in defaults)")
      ->check(CLI::ExistingFile);
  run->add_option("--hw-set", ro.hw_sets, "cycle: override one parameter, section.key=value; repeatable");
  run->add_option("--vcd", ro.vcd, "cycle: write a VCD waveform of unit activities and FIFO occupancies");
  run->add_option("--vcd-window", ro.vcd_window, "cycle: cycles FIRST:LAST the waveform follows (default all)");
  run->add_flag("--lockstep", ro.lockstep,
                "cycle: run every unit in lockstep with SystemC time, none decoupled (same results, slower; "
                "for checking the decoupling)");
  run->add_option("--repeat", ro.repeat, "Draw the input this many times into one frame (default 1)")
      ->check(CLI::Range(1u, 1000u));
  run->add_flag("--vs-reference", ro.vs_reference, "Also run the A-buffer reference on the same stream and report the RMSE");
  run->add_flag("--quiet", ro.quiet, "Print nothing on success");

  // compare
  std::string cmp_a, cmp_b;
  bool cmp_json = false;
  CLI::App* cmp = app.add_subcommand("compare", "RMSE (8-bit units) and PSNR of image A against image B (OpenImageIO)");
  cmp->add_option("A", cmp_a, "Image")->required()->check(CLI::ExistingFile);
  cmp->add_option("B", cmp_b, "Reference image")->required()->check(CLI::ExistingFile);
  cmp->add_flag("--json", cmp_json, "Print JSON");

  // scene
  SceneParams sp;
  std::string scene_out, depth_mode = "plane", color_fmt = "rgb-f32", compression = "zstd";
  bool scene_list = false;
  CLI::App* scn = app.add_subcommand("scene", "Write a built-in scene as a trace file, or list the scenes");
  scn->add_option("NAME", sp.name, "Scene: " + join(scene_names()))->check(CLI::IsMember(scene_names()));
  scn->add_option("--spp", sp.spp, "Samples per pixel: 1, 2, 4, 8, 16, 32 or 64 (default 16)")->check(CLI::IsMember({1, 2, 4, 8, 16, 32, 64}));
  scn->add_option("-o,--output", scene_out, "Trace file to write");
  scn->add_option("--width", sp.width, "Width in pixels (default: the scene's)")->check(CLI::Range(1u, kMaxScreenSide));
  scn->add_option("--height", sp.height, "Height in pixels (default: the scene's)")->check(CLI::Range(1u, kMaxScreenSide));
  scn->add_option("--seed", sp.seed, "Scene generator seed (default 1)");
  scn->add_option("--depth", depth_mode, "Depth records: plane or per-sample (default plane)")->check(CLI::IsMember({"plane", "per-sample"}));
  scn->add_option("--color", color_fmt, "Colour records: rgb-f32 or rgb-unorm8 (default rgb-f32)")->check(CLI::IsMember({"rgb-f32", "rgb-unorm8"}));
  scn->add_option("--compression", compression, "zstd or none (default zstd)")->check(CLI::IsMember({"zstd", "none"}));
  scn->add_flag("--list", scene_list, "List the built-in scenes");

  // trace
  CLI::App* trc = app.add_subcommand("trace", "Inspect a trace file");
  trc->require_subcommand(1);
  std::string trace_path;
  uint64_t dump_limit = UINT64_MAX;
  CLI::App* tinfo = trc->add_subcommand("info", "Header and statistics (streams the whole trace)");
  tinfo->add_option("FILE", trace_path, "Trace file")->required();
  CLI::App* tval = trc->add_subcommand("validate", "Check every record; exit 1 naming the first bad one");
  tval->add_option("FILE", trace_path, "Trace file")->required();
  CLI::App* tdump = trc->add_subcommand("dump", "Header and fragments as JSON lines");
  tdump->add_option("FILE", trace_path, "Trace file")->required();
  tdump->add_option("--limit", dump_limit, "Dump at most this many fragments");

  // vectors
  std::string vec_unit, vec_out;
  uint64_t vec_count = 1000, vec_seed = 1;
  Numerics vec_num;
  CLI::App* vec = app.add_subcommand("vectors", "Golden test vectors (CSV) for one unit, for RTL verification");
  vec->add_option("UNIT", vec_unit, "Unit: " + join(vector_units()))->required()->check(CLI::IsMember(vector_units()));
  vec->add_option("--count", vec_count, "Number of vectors (default 1000)")->check(CLI::Range(uint64_t{1}, uint64_t{100000000}));
  vec->add_option("-o,--output", vec_out, "CSV file to write")->required();
  vec->add_option("--seed", vec_seed, "Seed of the random cases (default 1)");
  vec->add_option("--hash-bits", vec_num.hash_bits, "alpha-ref: hash width (8..32)")->check(CLI::Range(8, 32));
  vec->add_option("--surface-id-bits", vec_num.surface_id_bits, "tracker: surface id width (1..32)")->check(CLI::Range(1, 32));

  // config
  std::string cfg_check;
  bool cfg_markdown = false;
  CLI::App* cfgc = app.add_subcommand("config", "Print the hardware config (defaults or a file, resolved) or its parameter table");
  cfgc->add_option("FILE", cfg_check, "Config file to check and print resolved (default: the built-in defaults)")
      ->check(CLI::ExistingFile);
  cfgc->add_flag("--markdown", cfg_markdown, "Print every parameter with unit, default, range and meaning (docs/config.md)");
  auto run_capture = add_capture_command(app);  // capture: sim/cli/cmd_capture.cpp
  bool rf_markdown = false;
  CLI::App* rfc = app.add_subcommand("report-fields", "List every report field with its unit and meaning");
  rfc->add_flag("--markdown", rf_markdown, "As the Markdown table of docs/reports.md");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }

  try {
    if (int rc = run_capture(); rc >= 0) return rc;
    if (run->parsed()) return cmd_run(ro, *run, cmdline);
    if (cmp->parsed()) {
      CompareResult c = compare_image_files(cmp_a, cmp_b);
      if (cmp_json)
        fmt::print("{{\"rmse_8bit\": {:.6f}, \"psnr_db\": {:.4f}, \"max_error_8bit\": {:.6f}, \"mean_error_8bit\": {:.6f}}}\n",
                   c.rmse_8bit, std::isfinite(c.psnr_db) ? c.psnr_db : 999.0, c.max_error_8bit, c.mean_error_8bit);
      else
        fmt::print("RMSE {:.4f} (8-bit units)  PSNR {:.2f} dB  max error {:.2f}\n", c.rmse_8bit, c.psnr_db, c.max_error_8bit);
      return 0;
    }
    if (scn->parsed()) {
      if (scene_list) {
        for (const auto& s : scene_catalog()) fmt::print("{:<13} {:>4}x{:<4} {}\n", s.name, s.width, s.height, s.description);
        return 0;
      }
      if (!scn->count("NAME")) throw UserError("scene: give a scene NAME (or --list)");
      if (scene_out.empty()) throw UserError("scene: give -o FILE");
      sp.depth_mode = depth_mode == "plane" ? DepthMode::kPlane : DepthMode::kPerSample;
      sp.color_format = color_fmt == "rgb-f32" ? ColorFormat::kRgbF32 : ColorFormat::kRgbUnorm8;
      sp.compression = compression == "zstd" ? Compression::kZstd : Compression::kNone;
      ensure_parent_dir(scene_out);
      RasterStats st = write_scene_trace(sp, scene_out);
      fmt::print("wrote {}: {} triangles, {} fragments, {} covered samples\n", scene_out, st.triangles, st.fragments,
                 st.covered_samples);
      return 0;
    }
    if (cfgc->parsed()) {
      if (cfg_markdown) {
        std::fputs(hw_params_markdown().c_str(), stdout);
        return 0;
      }
      HwConfig c = cfg_check.empty() ? HwConfig{} : load_hw_config(cfg_check);
      fmt::print("# ropsim hardware config: {}\n{}", c.name, hw_config_to_toml(c));
      return 0;
    }
    if (rfc->parsed()) {
      const auto docs = report_field_docs();
      if (rf_markdown) {
        std::fputs(fields_markdown(docs).c_str(), stdout);
      } else {
        for (const auto& d : docs) fmt::print("{:<52} {:<12} {}\n", d.path, d.unit, d.meaning);
      }
      return 0;
    }
    if (tinfo->parsed()) return cmd_trace_info(trace_path, false);
    if (tval->parsed()) return cmd_trace_info(trace_path, true);
    if (tdump->parsed()) return cmd_trace_dump(trace_path, dump_limit);
    if (vec->parsed()) {
      if (const char* err = validate(vec_num)) throw UserError(err);
      std::string csv = make_vectors(vec_unit, vec_count, vec_seed, vec_num);
      ensure_parent_dir(vec_out);
      write_text_file_atomic(vec_out, csv);
      fmt::print("wrote {}: {} vectors for {}\n", vec_out, vec_count, vec_unit);
      return 0;
    }
  } catch (const std::exception& e) {
    std::fflush(stdout);
    std::fprintf(stderr, "ropsim: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
