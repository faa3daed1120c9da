// `ropsim run`: replay a trace or a built-in scene through one fidelity;
// write images, a JSON report (and a VCD waveform).
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
#include "sim/cli/run_options.h"
#include "sim/cli/run_outputs.h"
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

using namespace cli;

namespace {

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

}  // namespace ropsim
