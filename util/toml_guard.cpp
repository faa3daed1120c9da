#include "toml_guard.h"

#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>

namespace ropsim {

namespace {

class Scanner {
 public:
  explicit Scanner(std::string_view t) : t_(t) {}

  TomlGuardProblem run() {
    // The last byte outside strings and comments that is not a blank: a quote
    // opens a string only where TOML lets one start (at the start of a line,
    // after '=', '[', '{' or ','; not after '.', which ends a float as well as a
    // dotted key's part: a quoted dotted key with UTF-8 is refused); elsewhere the parser does not read a
    // string there but scans on, testing what follows as a value would be.
    unsigned char last = '\n';
    while (i_ < t_.size() && !problem_) {
      const unsigned char c = byte(i_);
      const bool string_may_start = last == '\n' || last == '=' || last == '[' || last == '{' || last == ',';
      if (c != ' ' && c != '\t' && c != '\r') last = c;
      if (c == '#') {
        skip_comment();
      } else if ((c == '"' || c == '\'') && !string_may_start) {
        advance(1);
      } else if (c == '"') {
        if (starts("\"\"\"")) {
          advance(3);
          ml_basic();
        } else {
          advance(1);
          basic();
        }
      } else if (c == '\'') {
        if (starts("'''")) {
          advance(3);
          ml_literal();
        } else {
          advance(1);
          literal();
        }
      } else if (c >= 0x80) {
        fail(i_, "non-ASCII character outside a string or comment (TOML allows it only in strings and comments)");
      } else {
        advance(1);
      }
    }
    return problem_;
  }

 private:
  unsigned char byte(size_t i) const { return static_cast<unsigned char>(t_[i]); }
  bool starts(std::string_view s) const { return t_.substr(i_, s.size()) == s; }

  void advance(size_t n) {
    for (size_t k = 0; k < n && i_ < t_.size(); ++k, ++i_) {
      if (t_[i_] == '\n') {
        ++line_;
        line_start_ = i_ + 1;
      }
    }
  }

  void fail(size_t at, std::string what) {
    // Line and column of `at` (at >= line_start_ always: fail is called
    // before advancing past a newline after at).
    problem_.line = line_;
    problem_.column = at - line_start_ + 1;
    problem_.what = std::move(what);
  }

  void skip_comment() {
    while (i_ < t_.size() && t_[i_] != '\n') advance(1);
  }

  /// The byte after a backslash in a basic string (i_ at the backslash).
  bool escape_ok() {
    if (i_ + 1 < t_.size() && byte(i_ + 1) >= 0x80) {
      fail(i_ + 1, "non-ASCII character after a backslash in a string (not a TOML escape)");
      return false;
    }
    return true;
  }

  void basic() {
    while (i_ < t_.size() && !problem_) {
      const char c = t_[i_];
      if (c == '\n') return;  // unterminated: the parser reports it
      if (c == '"') {
        advance(1);
        return;
      }
      if (c == '\\') {
        if (!escape_ok()) return;
        advance(2);
        continue;
      }
      advance(1);
    }
  }

  void literal() {
    while (i_ < t_.size() && t_[i_] != '\n') {
      if (t_[i_] == '\'') {
        advance(1);
        return;
      }
      advance(1);
    }
  }

  static bool ws(char c) { return c == ' ' || c == '\t'; }

  void ml_basic() {
    while (i_ < t_.size() && !problem_) {
      if (starts("\"\"\"")) {
        advance(3);
        for (int k = 0; k < 2 && i_ < t_.size() && t_[i_] == '"'; ++k) advance(1);  // """" and """"" end in quotes
        return;
      }
      if (t_[i_] == '\\') {
        if (!escape_ok()) return;
        size_t j = i_ + 1;
        if (j < t_.size() && (ws(t_[j]) || t_[j] == '\n' || t_[j] == '\r')) {
          // A backslash then whitespace: the parser skips the blanks and
          // newlines that follow, testing each character for whitespace, the
          // first non-blank one included.
          while (j < t_.size() && (ws(t_[j]) || t_[j] == '\n' || t_[j] == '\r')) ++j;
          advance(j - i_);
          if (i_ < t_.size() && byte(i_) >= 0x80) {
            fail(i_,
                 "non-ASCII character first after a line-ending backslash (toml++ 3.3.0 cannot read it; "
                 "put an ASCII character or an escape such as \\u00e9 first)");
            return;
          }
          continue;
        }
        advance(2);
        continue;
      }
      advance(1);
    }
  }

  void ml_literal() {
    while (i_ < t_.size()) {
      if (starts("'''")) {
        advance(3);
        for (int k = 0; k < 2 && i_ < t_.size() && t_[i_] == '\''; ++k) advance(1);
        return;
      }
      advance(1);
    }
  }

  std::string_view t_;
  size_t i_ = 0;
  size_t line_ = 1;
  size_t line_start_ = 0;
  TomlGuardProblem problem_;
};

}  // namespace

TomlGuardProblem toml_guard(std::string_view text) { return Scanner(text).run(); }

bool read_text_file(const std::string& path, std::string& out) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return false;
  std::ifstream f(path, std::ios::binary);
  if (!f) return false;
  std::ostringstream ss;
  ss << f.rdbuf();
  if (f.bad()) return false;
  out = ss.str();
  return true;
}

std::string toml_guard_message(std::string_view text, const std::string& path) {
  const TomlGuardProblem p = toml_guard(text);
  if (!p) return "";
  return path + ":" + std::to_string(p.line) + ":" + std::to_string(p.column) + ": " + p.what;
}

}  // namespace ropsim
