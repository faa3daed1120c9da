// Shared by the verbs of the ropsim command line (one source file per verb:
// cmd_run.cpp, cmd_scene.cpp, cmd_trace.cpp, cmd_vectors.cpp, cmd_config.cpp,
// cmd_compare.cpp, cmd_capture.cpp, cmd_report_fields.cpp; main.cpp only
// dispatches).
//
// Each add_*_command registers its verb on the app and returns a function
// that, called after parsing, runs the verb and returns the exit status, or -1
// when that verb was not the one given. Errors are thrown: UserError (and the
// per-module error types) for the user, InternalError for a broken invariant;
// main maps them to the exit status (README "Exit status").
#pragma once
#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <vector>

#include "errors.h"
#include "output_file.h"
#include "progress.h"
#include "scenes.h"

namespace ropsim {

using VerbRunner = std::function<int()>;

VerbRunner add_run_command(CLI::App& app, const std::string& command_line);
VerbRunner add_livepoints_command(CLI::App& app);
VerbRunner add_compare_command(CLI::App& app);
VerbRunner add_scene_command(CLI::App& app);
VerbRunner add_trace_command(CLI::App& app);
VerbRunner add_vectors_command(CLI::App& app);
VerbRunner add_config_command(CLI::App& app);
VerbRunner add_report_fields_command(CLI::App& app);
VerbRunner add_study_command(CLI::App& app);
// add_capture_command: cmd_capture.h

/// The progress mode of a verb's run (util/progress.h): none with --quiet,
/// forced into logs with --progress, else on a terminal only.
inline void set_progress_flags(bool quiet, bool force) {
  set_progress_mode(quiet ? ProgressMode::kOff : force ? ProgressMode::kAlways : ProgressMode::kTerminal);
}

inline std::string join(const std::vector<std::string>& v, const char* sep = ", ") {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : sep) + x;
  return s;
}

inline std::vector<std::string> scene_names() {
  std::vector<std::string> v;
  for (const auto& s : scene_catalog()) v.push_back(s.name);
  return v;
}

}  // namespace ropsim
