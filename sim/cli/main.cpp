// ropsim: command-line entry point. Only dispatches: builds the CLI11 app,
// registers the verbs (one source file each, cli_common.h) and maps what they
// throw to the exit status by the one rule of util/errors.h (README "Exit status"):
//   0  success (and --help, --version)
//   1  user error: a bad trace, config, scene, flag or input, or an output
//      that cannot be written. One line "ropsim: error: ...".
//   2  internal error: an invariant of the simulator does not hold.
//      One line "ropsim: internal error: <invariant>: please report it".
// A failing run removes the outputs it created (never a file it replaced).
// Standard output is flushed and checked once, at the end (a failed write
// is a user error; a reader that closed it ends ropsim quietly, as SIGPIPE).
#include <CLI/CLI.hpp>
#include <cstdio>
#include <string>
#include <system_error>
#include <vector>

#include "sim/cli/cli_common.h"
#include "sim/cli/cmd_capture.h"
#include "util/errors.h"
#include "util/host_threads.h"
#include "util/memory_budget.h"
#include "util/output_file.h"
#include "util/version.h"

using namespace ropsim;

namespace {

/// Reports an error classified by the one rule (util/errors.h): removes the
/// outputs this run created, prints the one line, returns the exit status.
int report(const ErrorVerdict& v) {
  std::fflush(stdout);
  remove_created_outputs();
  std::fprintf(stderr, "ropsim: %s\n", v.message().c_str());
  return v.status;
}

}  // namespace

int main(int argc, char** argv) {
  install_output_signal_handling();  // SIGXFSZ, SIGPIPE ignored: write errors, reported by the writer
  CLI::App app{"ropsim: a simulator of a GPU ROP for stratified stochastic transparency (Laine & Karras 2011)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("ropsim ") + ropsim_version() + " (commit " + ropsim_commit() + ")",
                       "Print the version and the source commit");
  // Every user error is one line: CLI11's default adds a second "Run with --help" line.
  app.failure_message([](const CLI::App*, const CLI::Error& e) {
    return "ropsim: error: " + std::string(e.what()) + " (see --help)\n";
  });
  // Global: before or after the verb (fallthrough), for every verb that simulates.
  std::string memory_limit;
  CLI::Option* opt_memory_limit =
      app.add_option("--memory-limit", memory_limit,
                     "Most memory the run's growing state may take (the touched tiles' buffers, the image, the "
                     "A-buffer reference, the timing model's structures): bytes with K, M, G or T (binary), a "
                     "percentage of physical memory, or "
                     "none for no limit (0 and an empty value are refused); default 80%. Going over is a one-line "
                     "error")
          ->type_name("SIZE");
  double output_timeout = -1;
  CLI::Option* opt_output_timeout =
      app.add_option("--output-timeout", output_timeout,
                     "Seconds an output that is a FIFO waits for its reader before ropsim gives up with an error "
                     "(0: do not wait; default: wait as long as it takes, saying once on stderr that it waits)")
          ->check(CLI::Range(0.0, 1e9))
          ->type_name("SECONDS");
  int threads = 0;
  app.add_option("--threads", threads,
                 "Host threads of the golden model (the functional fidelity, the reference pre-pass of a cycle "
                 "run); the result is bit-identical for every count. Default: every core this process may use")
      ->check(in_range(1, 1024))
      ->type_name("N");
  app.fallthrough();
  std::string cmdline;
  for (int i = 0; i < argc; ++i) cmdline += (i ? " " : "") + std::string(argv[i]);

  const std::vector<VerbRunner> verbs = {add_run_command(app, cmdline), add_compare_command(app),
                                         add_scene_command(app),        add_trace_command(app),
                                         add_vectors_command(app),      add_config_command(app),
                                         add_capture_command(app),      add_report_fields_command(app),
                                         add_study_command(app),        add_livepoints_command(app)};
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);  // prints help, the version or the one-line error
    if (rc == 0) {               // --help, --version: on std::cout, synchronised with stdout
      try {
        finish_standard_output();
      } catch (...) {
        return report(classify_current_exception());
      }
    }
    return rc == 0 ? 0 : 1;  // CLI11's own codes (105, 106...) are all "bad flag"
  }

  try {
    // Test hook (tests/test_output.cpp, tests/test_errors.cpp): exercises the exit status 2 path.
    test_hook_internal_error("main");
    if (opt_memory_limit->count()) memory_budget().set_limit(parse_memory_size(memory_limit, "--memory-limit"));
    if (opt_output_timeout->count()) set_output_timeout(output_timeout);
    if (threads > 0) set_host_threads(threads);
    for (const auto& verb : verbs)
      if (const int rc = verb(); rc >= 0) {
        finish_standard_output();  // what the verb printed must have arrived
        forget_created_outputs();
        return rc;
      }
    finish_standard_output();
    return 0;
  } catch (const std::system_error& e) {
    // fmt::print (every verb's printing to standard output) throws this when the write fails.
    // That is the standard output's error, said as such (or a quiet end on EPIPE).
    if (std::string(e.what()).rfind("cannot write to file", 0) == 0) {
      try {
        standard_output_failed(e.code().value());
      } catch (...) {
        return report(classify_current_exception());
      }
    }
    return report(classify_current_exception());
  } catch (...) {
    return report(classify_current_exception());
  }
}
