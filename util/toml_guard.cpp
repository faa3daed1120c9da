#include "util/toml_guard.h"

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>

namespace ropsim {

namespace {

class Rewriter {
 public:
  Rewriter(std::string_view t, std::string* out) : t_(t), out_(out) {
    if (out_) {
      out_->clear();
      out_->reserve(t.size() + t.size() / 8);
    }
  }

  TomlGuardProblem run() {
    if (t_.substr(0, 3) == "\xEF\xBB\xBF") i_ = 3, line_start_ = 3;  // a byte order mark
    while (i_ < t_.size() && !problem_) {
      const unsigned char c = byte(i_);
      if (c == '#') {
        comment();
      } else if (c == '"') {
        if (starts("\"\"\"")) {
          copy(3);
          basic(true);
        } else {
          copy(1);
          basic(false);
        }
      } else if (c == '\'') {
        literal(starts("'''"));
      } else if (c >= 0x80) {
        fail(i_, "non-ASCII character outside a string or comment (TOML allows it only in strings and comments)");
      } else {
        copy(1);
      }
    }
    return problem_;
  }

 private:
  unsigned char byte(size_t i) const { return static_cast<unsigned char>(t_[i]); }
  bool starts(std::string_view s) const { return t_.substr(i_, s.size()) == s; }

  void emit(std::string_view s) {
    if (out_) out_->append(s);
  }
  void emit(char c) {
    if (out_) out_->push_back(c);
  }

  /// Consumes n ASCII bytes, copying them.
  void copy(size_t n) {
    for (size_t k = 0; k < n && i_ < t_.size(); ++k) {
      emit(t_[i_]);
      step();
    }
  }

  void step() {
    if (t_[i_] == '\n') {
      ++line_;
      line_start_ = i_ + 1;
    }
    ++i_;
  }

  void fail(size_t at, std::string what) {
    problem_.line = line_;
    problem_.column = at - line_start_ + 1;
    problem_.what = std::move(what);
  }

  /// The code point of the UTF-8 sequence at i_ (its first byte >= 0x80) and
  /// its length; 0 and a problem if malformed (overlong, a surrogate, beyond
  /// U+10FFFF, truncated, or a stray continuation byte).
  size_t decode(uint32_t& cp) {
    const unsigned char b0 = byte(i_);
    size_t n = 0;
    uint32_t min = 0;
    if (b0 >= 0xC2 && b0 <= 0xDF) {
      n = 2, cp = b0 & 0x1F, min = 0x80;
    } else if (b0 >= 0xE0 && b0 <= 0xEF) {
      n = 3, cp = b0 & 0x0F, min = 0x800;
    } else if (b0 >= 0xF0 && b0 <= 0xF4) {
      n = 4, cp = b0 & 0x07, min = 0x10000;
    }
    bool ok = n != 0 && i_ + n <= t_.size();
    for (size_t k = 1; ok && k < n; ++k) {
      const unsigned char b = byte(i_ + k);
      ok = (b & 0xC0) == 0x80;
      cp = (cp << 6) | (b & 0x3F);
    }
    ok = ok && cp >= min && cp <= 0x10FFFF && !(cp >= 0xD800 && cp <= 0xDFFF);
    if (!ok) {
      fail(i_, "malformed UTF-8 (TOML files are UTF-8)");
      return 0;
    }
    return n;
  }

  /// A non-ASCII character at i_, written as `replacement` or, if that is
  /// empty, as its escape.
  void non_ascii(const char* replacement) {
    uint32_t cp = 0;
    const size_t n = decode(cp);
    if (n == 0) return;
    if (replacement) {
      emit(replacement);
    } else {
      char buf[12];
      if (cp <= 0xFFFF) {
        std::snprintf(buf, sizeof buf, "\\u%04X", static_cast<unsigned>(cp));
      } else {
        std::snprintf(buf, sizeof buf, "\\U%08X", static_cast<unsigned>(cp));
      }
      emit(buf);
    }
    i_ += n;
  }

  void comment() {
    while (i_ < t_.size() && t_[i_] != '\n' && !problem_) {
      if (byte(i_) >= 0x80) {
        non_ascii("?");
      } else {
        copy(1);
      }
    }
  }

  /// A basic string's body, i_ after its opening quote(s); ends after the
  /// closing quote(s), or at the line's end if a one-line string is not
  /// closed (the parser reports it), or at the text's end.
  void basic(bool multi) {
    while (i_ < t_.size() && !problem_) {
      const unsigned char c = byte(i_);
      if (!multi && c == '\n') return;
      if (multi && starts("\"\"\"")) {
        copy(3);
        for (int k = 0; k < 2 && i_ < t_.size() && t_[i_] == '"'; ++k) copy(1);  // """" and """"" end in quotes
        return;
      }
      if (!multi && c == '"') {
        copy(1);
        return;
      }
      if (c == '\\') {
        if (i_ + 1 < t_.size() && byte(i_ + 1) >= 0x80) {
          fail(i_ + 1, "non-ASCII character after a backslash in a string (not a TOML escape)");
          return;
        }
        copy(2);  // an escape, or a line-ending backslash and the blank or newline after it
        continue;
      }
      if (c >= 0x80) {
        non_ascii(nullptr);
      } else {
        copy(1);
      }
    }
  }

  /// A literal string, i_ at its opening quote(s). Copied as it is when it is
  /// all ASCII, else written as the basic string of the same value.
  void literal(bool multi) {
    const size_t open = multi ? 3 : 1;
    size_t end = i_ + open;  // one past the closing quote(s), or where the string stops
    bool closed = false, ascii = true;
    while (end < t_.size()) {
      if (!multi && t_[end] == '\n') break;
      if (multi ? t_.substr(end, 3) == "'''" : t_[end] == '\'') {
        end += open;
        for (int k = 0; multi && k < 2 && end < t_.size() && t_[end] == '\''; ++k) ++end;
        closed = true;
        break;
      }
      ascii = ascii && byte(end) < 0x80;
      ++end;
    }
    if (ascii || !closed) {
      // All ASCII, or not closed: nothing to rewrite for the value's sake; a
      // non-ASCII byte in an unclosed string becomes an escape inside what
      // the parser sees as a broken literal, so it stays an error there.
      while (i_ < end && !problem_) {
        if (byte(i_) >= 0x80) {
          non_ascii("?");
        } else {
          copy(1);
        }
      }
      return;
    }
    const size_t body_end = end - open;
    emit(multi ? "\"\"\"" : "\"");
    i_ += open;
    while (i_ < body_end && !problem_) {
      const unsigned char c = byte(i_);
      if (c == '\\' || c == '"') {
        emit('\\');
        copy(1);
      } else if (c >= 0x80) {
        non_ascii(nullptr);
      } else {
        copy(1);
      }
    }
    emit(multi ? "\"\"\"" : "\"");
    i_ = end;
  }

  std::string_view t_;
  std::string* out_;
  size_t i_ = 0;
  size_t line_ = 1;
  size_t line_start_ = 0;
  TomlGuardProblem problem_;
};

}  // namespace

TomlGuardProblem toml_guard(std::string_view text, std::string* ascii) { return Rewriter(text, ascii).run(); }

TomlInput toml_input(std::string_view text, const std::string& path) {
  TomlInput in;
  const TomlGuardProblem p = toml_guard(text, &in.ascii);
  if (p) {
    in.ascii.clear();
    in.error = path + ":" + std::to_string(p.line) + ":" + std::to_string(p.column) + ": " + p.what;
  }
  return in;
}

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

}  // namespace ropsim
