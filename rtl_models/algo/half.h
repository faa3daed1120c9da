// IEEE binary16 storage for per-sample colour (an RGB16F render target).
#pragma once
#include <cstdint>
#include <cstring>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

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

#if defined(__SSE2__)
/// half_to_float of four lanes, each binary16 in the low 16 bits of a 32-bit
/// lane (the high bits zero): the same operations lane by lane, bit for bit.
inline __m128 half4_to_float4(__m128i h) {
  const __m128i x = _mm_slli_epi32(_mm_and_si128(h, _mm_set1_epi32(0x7FFF)), 13);
  __m128i r = _mm_castps_si128(_mm_mul_ps(_mm_castsi128_ps(x), _mm_set1_ps(0x1p112f)));
  const __m128i inf_nan = _mm_cmpeq_epi32(_mm_and_si128(h, _mm_set1_epi32(0x7C00)), _mm_set1_epi32(0x7C00));
  r = _mm_or_si128(r, _mm_and_si128(inf_nan, _mm_set1_epi32(0x7F800000)));
  return _mm_castsi128_ps(_mm_or_si128(r, _mm_slli_epi32(_mm_and_si128(h, _mm_set1_epi32(0x8000)), 16)));
}

/// float_to_half of four lanes, each result in the low 16 bits of its 32-bit
/// lane (the high bits zero). Equal to float_to_half on every binary32 value
/// (checked exhaustively when written; tests/test_algo.cpp checks a stride of
/// them): the normal case is float_to_half's; a subnormal or zero result is
/// the binary32 sum |f| + 0.5, whose unit in the last place is 2^-24, the
/// binary16 subnormal's unit, so the addition's round to nearest even is the
/// rounding float_to_half does by shifts; |f| >= 65536 gives inf or the quiet
/// NaN (|f| in [65520, 65536) reaches inf through the normal case's carry).
inline __m128i float4_to_half4(__m128 f) {
  const __m128i x = _mm_castps_si128(f);
  const __m128i sign = _mm_and_si128(x, _mm_set1_epi32(int(0x80000000u)));
  const __m128i absx = _mm_xor_si128(x, sign);
  const __m128i lsb = _mm_and_si128(_mm_srli_epi32(absx, 13), _mm_set1_epi32(1));
  const __m128i normal =
      _mm_srli_epi32(_mm_add_epi32(_mm_add_epi32(absx, _mm_set1_epi32(int(0xFFFu - 0x38000000u))), lsb), 13);
  const __m128i sub = _mm_sub_epi32(_mm_castps_si128(_mm_add_ps(_mm_castsi128_ps(absx), _mm_set1_ps(0.5f))),
                                    _mm_set1_epi32(0x3F000000));
  const __m128i inf_nan = _mm_or_si128(
      _mm_set1_epi32(0x7C00), _mm_and_si128(_mm_cmpgt_epi32(absx, _mm_set1_epi32(0x7F800000)), _mm_set1_epi32(0x200)));
  const __m128i big = _mm_cmpgt_epi32(absx, _mm_set1_epi32(0x477FFFFF));  // |f| >= 65536 (signed compare: absx < 2^31)
  const __m128i small = _mm_cmplt_epi32(absx, _mm_set1_epi32(0x38800000));  // |f| < 2^-14
  __m128i h = _mm_or_si128(_mm_and_si128(small, sub), _mm_andnot_si128(small, normal));
  h = _mm_or_si128(_mm_and_si128(big, inf_nan), _mm_andnot_si128(big, h));
  return _mm_or_si128(h, _mm_srli_epi32(sign, 16));
}

/// Four binary16 values (8 bytes at p, unaligned) into 32-bit lanes, and back.
inline __m128i load_half4(const void* p) {
  return _mm_unpacklo_epi16(_mm_loadl_epi64(static_cast<const __m128i*>(p)), _mm_setzero_si128());
}
inline void store_half4(void* p, __m128i h) {
  // Each lane is below 2^16: shifted up and back (sign-extending), the signed
  // saturating pack keeps it exactly.
  const __m128i s = _mm_srai_epi32(_mm_slli_epi32(h, 16), 16);
  _mm_storel_epi64(static_cast<__m128i*>(p), _mm_packs_epi32(s, s));
}
#endif

}  // namespace ropsim
