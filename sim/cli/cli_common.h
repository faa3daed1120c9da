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
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <cstdlib>
#include <functional>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

#include "traces/scenes/scenes.h"
#include "util/errors.h"
#include "util/output_file.h"
#include "util/progress.h"

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

/// A number in [lo, hi]. Help and errors show the range as "lo..hi", or as
/// ">= lo" when hi is the type's largest (CLI::Range would print its digits);
/// a negative value for an unsigned option is refused here, before CLI11's
/// conversion could wrap it. The error, after CLI11's "--flag: ", is
/// "VALUE: must be >= 1".
template <class T>
CLI::Validator in_range(T lo, T hi = std::numeric_limits<T>::max()) {
  static_assert(std::is_arithmetic_v<T>, "a numeric option");
  const bool open = hi == std::numeric_limits<T>::max();
  const std::string range = open ? fmt::format(">= {}", lo) : fmt::format("{}..{}", lo, hi);
  const std::string must = open ? "must be " + range : "must be in " + range;
  return CLI::Validator(
      [lo, hi, must](std::string& text) -> std::string {
        const char* s = text.c_str();
        char* end = nullptr;
        const long double v = std::strtold(s, &end);
        if (end == s || *end != '\0' || v != v) return text + ": not a number";
        if (v < static_cast<long double>(lo) || v > static_cast<long double>(hi)) return text + ": " + must;
        return "";
      },
      range);
}

/// A verb's --help footer: its examples, each a whole command line that runs
/// as written from the checkout (after the scene and run examples have made
/// cloth.trace, lk.exr and reference.exr; tests/test_cli.cpp runs them all).
inline std::string examples(const std::vector<std::string>& lines) {
  std::string s = "Examples:";
  for (const auto& l : lines) s += "\n  " + l;
  return s;
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
