// A check every TOML input passes before toml++ sees it.
//
// Debian's toml++ 3.3.0 reaches __builtin_unreachable (undefined behaviour)
// when it tests a non-ASCII character for whitespace (marzer/tomlplusplus#190,
// fixed upstream after 3.3.0): is_non_ascii_horizontal_whitespace() falls
// through its switch for most code points in U+00A1..U+FEFF. The parser asks
// that question only where TOML allows nothing but ASCII: outside strings and
// comments (between tokens, after a value, at the start of a line), after a
// backslash in a basic string, and where a line-ending backslash in a
// multi-line basic string skips the whitespace that follows it. This check
// refuses exactly those places, so the parser's undefined path is never
// reached; UTF-8 inside strings and comments is untouched.
#pragma once
#include <cstddef>
#include <string>
#include <string_view>

namespace ropsim {

struct TomlGuardProblem {
  size_t line = 0;    ///< 1-based; 0: no problem
  size_t column = 0;  ///< 1-based, in bytes
  std::string what;   ///< e.g. "non-ASCII character outside a string or comment"
  explicit operator bool() const { return line != 0; }
};

/// The first place in text where toml++ 3.3.0 would test a non-ASCII
/// character for whitespace, or an empty problem. Never throws.
TomlGuardProblem toml_guard(std::string_view text);

/// Reads a whole regular file (a TOML input) into out; false if it is not a
/// regular file or cannot be read.
bool read_text_file(const std::string& path, std::string& out);

/// toml_guard as a one-line message "PATH:LINE:COLUMN: WHAT", or "" if fine.
std::string toml_guard_message(std::string_view text, const std::string& path);

}  // namespace ropsim
