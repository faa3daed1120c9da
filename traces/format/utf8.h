// UTF-8 validation (RFC 3629): text a trace carries must be valid UTF-8 so
// that every reader -- JSON dumps, reports, terminals -- can carry it as is.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string_view>

namespace ropsim {

/// True when s is well-formed UTF-8: every sequence complete, no stray
/// continuation byte, no overlong encoding (C0 80 for NUL, E0 80 80, ...),
/// no UTF-16 surrogate (U+D800..U+DFFF) and nothing above U+10FFFF.
/// The empty string and ASCII (NUL included) are valid.
inline bool is_valid_utf8(std::string_view s) {
  const size_t n = s.size();
  for (size_t i = 0; i < n;) {
    const auto lead = static_cast<unsigned char>(s[i]);
    if (lead < 0x80) {
      ++i;
      continue;
    }
    size_t len;
    uint32_t cp, min;
    if ((lead & 0xE0) == 0xC0) {
      len = 2, cp = lead & 0x1Fu, min = 0x80;
    } else if ((lead & 0xF0) == 0xE0) {
      len = 3, cp = lead & 0x0Fu, min = 0x800;
    } else if ((lead & 0xF8) == 0xF0) {
      len = 4, cp = lead & 0x07u, min = 0x10000;
    } else {
      return false;  // a continuation byte (80..BF) without a lead, or F8..FF
    }
    if (n - i < len) return false;  // truncated
    for (size_t k = 1; k < len; ++k) {
      const auto c = static_cast<unsigned char>(s[i + k]);
      if ((c & 0xC0) != 0x80) return false;
      cp = cp << 6 | (c & 0x3Fu);
    }
    if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return false;
    i += len;
  }
  return true;
}

}  // namespace ropsim
