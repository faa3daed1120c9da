// `ropsim livepoints`: record the live-points of a sampled simulation into a
// library that `run --fidelity sampled --livepoints` reuses for every design.
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
