// Fixed-width lower-case hexadecimal, the one way ropsim prints a digest, a
// hash or a bit pattern: 16 digits for 64 bits, 8 for 32, no prefix.
#pragma once
#include <cstdint>
#include <cstdio>
#include <string>

namespace ropsim {

inline std::string hex64(uint64_t v) {
  char b[17];
  std::snprintf(b, sizeof b, "%016llx", static_cast<unsigned long long>(v));
  return b;
}

inline std::string hex32(uint32_t v) {
  char b[9];
  std::snprintf(b, sizeof b, "%08x", static_cast<unsigned>(v));
  return b;
}

}  // namespace ropsim
