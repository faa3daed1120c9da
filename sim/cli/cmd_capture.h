// `ropsim capture`: a mesh scene file -> a fragment trace (docs/capture.md).
#pragma once
#include <CLI/CLI.hpp>
#include <functional>

namespace ropsim {

/// Registers the `capture` subcommand on app. The returned function, called
/// after parsing, runs it and returns the exit status, or -1 when `capture`
/// was not the subcommand given. Errors are thrown (one line each).
std::function<int()> add_capture_command(CLI::App& app);

}  // namespace ropsim
