// IEEE binary16 storage for per-sample colour (an RGB16F render target).
#pragma once
#include <cstdint>
#include <cstring>

namespace ropsim {

/// binary32 -> binary16, round to nearest even; overflow -> inf, NaN kept.
inline uint16_t float_to_half(float f) {
  uint32_t x;
  std::memcpy(&x, &f, 4);
  const uint32_t sign = (x >> 16) & 0x8000u;
  const uint32_t absx = x & 0x7FFFFFFFu;
  if (absx >= 0x7F800000u) return static_cast<uint16_t>(sign | 0x7C00u | (absx > 0x7F800000u ? 0x200u : 0u));
  if (absx >= 0x477FF000u) return static_cast<uint16_t>(sign | 0x7C00u);  // rounds to >= 65520
  if (absx < 0x38800000u) {                                               // subnormal half or zero
    if (absx < 0x33000000u) return static_cast<uint16_t>(sign);           // < 2^-25 rounds to 0
    const uint32_t e = absx >> 23;
    const uint32_t m = (absx & 0x7FFFFFu) | 0x800000u;
    const uint32_t shift = 126 - e;  // 14 + (127 - 15 - e) ... maps to 2^-24 units
    uint32_t h = m >> shift;
    const uint32_t rem = m & ((1u << shift) - 1);
    const uint32_t half = 1u << (shift - 1);
    if (rem > half || (rem == half && (h & 1u))) ++h;
    return static_cast<uint16_t>(sign | h);
  }
  // Normal: rebias the exponent and round the 13 dropped bits to nearest
  // even without a data-dependent branch: adding 0xFFF plus the kept LSB
  // carries exactly when the rest is above half, or half with the LSB odd
  // (a carry out of the mantissa increments the exponent, as it must).
  const uint32_t h = (absx - 0x38000000u + 0xFFFu + ((absx >> 13) & 1u)) >> 13;
  return static_cast<uint16_t>(sign | h);
}

inline float half_to_float(uint16_t h) {
  // Exponent and mantissa moved into binary32 position, then scaled by
  // 2^(127 - 15) (exact, subnormal halves included: the product is a normal
  // binary32); an Inf or NaN half gets the all-ones exponent back, its
  // mantissa kept. No data-dependent branch.
  uint32_t x = uint32_t(h & 0x7FFFu) << 13;
  float f;
  std::memcpy(&f, &x, 4);
  f *= 0x1p112f;
  std::memcpy(&x, &f, 4);
  if ((h & 0x7C00u) == 0x7C00u) x |= 0x7F800000u;
  x |= uint32_t(h & 0x8000u) << 16;
  std::memcpy(&f, &x, 4);
  return f;
}

}  // namespace ropsim
