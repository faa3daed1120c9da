// `ropsim capture`: a mesh scene file -> a fragment trace; `ropsim capture gl`:
// a frame of an OpenGL application -> a trace (docs/capture.md).
#pragma once
#include <CLI/CLI.hpp>
#include <functional>

namespace ropsim {

/// Registers the `capture` subcommand on app. The returned function, called
/// after parsing, runs it and returns the exit status, or -1 when `capture`
/// was not the subcommand given. Errors are thrown (one line each).
std::function<int()> add_capture_command(CLI::App& app);

/// Registers `gl` under the `capture` subcommand (cmd_capture_gl.cpp). The
/// returned function runs it (call it only when `gl` was parsed).
std::function<int()> add_capture_gl_command(CLI::App& capture);

}  // namespace ropsim
