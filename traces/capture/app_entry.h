// Application entries (TOML, docs/capture.md "Application entries"): one
// frame of a real OpenGL application as a workload. An entry names the
// Debian package and the command line, the frame and the framebuffer to
// capture, its size and spp, and what the frame shows; `ropsim capture gl
// --app FILE` captures it, and a study names it as an input (`inputs.apps`),
// captured once per spp and size. An unknown key or a bad value is a
// CaptureError naming the file, the line and the key.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace ropsim {

struct AppEntry {
  std::string path;     ///< the entry file
  std::string name;     ///< `name`, else the file's stem: the input's name in studies
  std::string package;  ///< the Debian package that installs the application (scripts/deps.sh --apps)
  /// The application and its arguments; "{width}" and "{height}" in an
  /// argument become the capture's size (app_command).
  std::vector<std::string> command;
  int64_t frame = 0;                 ///< frames count from 0: the work after the frame-th buffer swap
  std::string target = "presented";  ///< presented, or fbo:N
  unsigned width = 0, height = 0;    ///< the virtual screen, pixels
  int spp = 1;                       ///< 1, 2, 4, 8, 16, 32 or 64
  double timeout = 120;              ///< seconds the application may take to reach the end of the frame
  bool large = false;                ///< too large a package for CI: installed on demand (scripts/deps.sh --apps)
  std::string shows;                 ///< what the frame shows, one line
};

/// What a capture of an entry may change: a study's axes, the command line.
struct AppOverrides {
  std::optional<int> spp;
  std::optional<unsigned> width, height;
  std::optional<int64_t> frame;
};

/// Reads and checks an entry file; applies the overrides (checked as the
/// file's own values are).
AppEntry load_app_entry(const std::string& path, const AppOverrides& o = {});
/// load_app_entry of an entry's text; path names it in errors.
AppEntry parse_app_entry(const std::string& text, const std::string& path, const AppOverrides& o = {});

/// The entry's command with "{width}" and "{height}" replaced by its size.
std::vector<std::string> app_command(const AppEntry& e);

}  // namespace ropsim
