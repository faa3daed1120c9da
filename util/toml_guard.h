// What every TOML input goes through before toml++ sees it.
//
// Debian's toml++ 3.3.0 reaches __builtin_unreachable (undefined behaviour)
// when it tests a non-ASCII character for whitespace (marzer/tomlplusplus#190,
// fixed upstream after 3.3.0): is_non_ascii_horizontal_whitespace() falls
// through its switch for most code points in U+00A1..U+FEFF. Where the parser
// asks that question depends on how it recovers from malformed input, so no
// list of places is complete (a fuzzer kept finding new ones). Instead the
// parser is given text that holds no non-ASCII byte at all:
//  - in a basic string ("..." and """..."""), each non-ASCII character becomes
//    its escape \uXXXX or \UXXXXXXXX, which means the same string;
//  - a literal string ('...' and '''...''') that holds one becomes the basic
//    string with the same value (backslashes and quotes escaped as well);
//  - in a comment, each non-ASCII character becomes '?';
//  - a UTF-8 byte order mark at the start is dropped (TOML allows it).
// A non-ASCII character anywhere else (outside strings and comments, where
// TOML forbids it, or right after a backslash, which is no escape) and
// malformed UTF-8 anywhere are refused with their line and column. The text
// keeps its lines, so the parser's line numbers stay the file's.
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

/// Writes `text` as pure ASCII TOML of the same meaning into *ascii (when not
/// null) and returns an empty problem, or returns the first place it cannot
/// (then *ascii is unspecified). Never throws but std::bad_alloc.
TomlGuardProblem toml_guard(std::string_view text, std::string* ascii = nullptr);

/// A TOML file's text as the parser is to see it, or why it cannot be.
struct TomlInput {
  std::string ascii;  ///< the text to give toml++ (only ASCII bytes)
  std::string error;  ///< "" or the one-line "PATH:LINE:COLUMN: WHAT"
};
TomlInput toml_input(std::string_view text, const std::string& path);

/// Reads a whole regular file (a TOML input) into out; false if it is not a
/// regular file or cannot be read.
bool read_text_file(const std::string& path, std::string& out);

}  // namespace ropsim
