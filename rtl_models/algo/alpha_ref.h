// CalcAlphaRef of Laine & Karras 2011, Figure 4: a scrambled radical-inverse
// opacity reference value per sample. The default 32-bit datapath is the
// paper's; hash_bits narrows it for what-if studies (docs/numerics.md).
#pragma once
#include <cstdint>
#if defined(__SSE4_1__) && defined(__SSSE3__)
#include <smmintrin.h>
#include <tmmintrin.h>
#endif

#include "rtl_models/algo/bits.h"
#include "rtl_models/algo/numerics.h"

namespace ropsim {

inline constexpr uint32_t kAlphaRefConstants[4] = {0x6C50B47Cu, 0xB82F1E52u, 0xC7AFE638u, 0x8D22F6E6u};

/// Sequence index of a sample: sampleId + pixelId * spp, kept modulo 2^hash_bits
/// (the paper's 32-bit unsigned arithmetic; wraps on screens where
/// pixelId * spp >= 2^32, see docs/numerics.md "Index overflow").
inline uint32_t alpha_ref_index(uint32_t sample_id, uint64_t pixel_id, uint32_t spp, int hash_bits = 32) {
  const uint64_t x = uint64_t{sample_id} + pixel_id * uint64_t{spp};
  return static_cast<uint32_t>(x & low_mask(hash_bits));
}

/// The hash of Figure 4 on a hash_bits-wide datapath. Returns an integer in
/// [0, 2^hash_bits); the reference value is that integer / 2^hash_bits.
inline uint32_t calc_alpha_ref_index(uint32_t index, uint32_t surface_id, int hash_bits = 32) {
  const uint32_t m = static_cast<uint32_t>(low_mask(hash_bits));
  uint32_t x = reverse_bits32(index & m) >> (32 - hash_bits);
  x = (x + surface_id) & m;
  for (uint32_t c : kAlphaRefConstants) x = (x ^ (x * (c & m))) & m;
  return x;
}

/// CalcAlphaRef(sampleId, pixelId, surfaceId) with the paper's 32-bit datapath.
inline uint32_t calc_alpha_ref(uint32_t sample_id, uint64_t pixel_id, uint32_t surface_id, uint32_t spp,
                               int hash_bits = 32) {
  return calc_alpha_ref_index(alpha_ref_index(sample_id, pixel_id, spp, hash_bits), surface_id, hash_bits);
}

#if defined(__SSE4_1__) && defined(__SSSE3__)
namespace alpha_ref_detail {
/// Each of kAlphaRefConstants in four lanes.
alignas(16) inline constexpr uint32_t kConstantsX4[4][4] = {
    {kAlphaRefConstants[0], kAlphaRefConstants[0], kAlphaRefConstants[0], kAlphaRefConstants[0]},
    {kAlphaRefConstants[1], kAlphaRefConstants[1], kAlphaRefConstants[1], kAlphaRefConstants[1]},
    {kAlphaRefConstants[2], kAlphaRefConstants[2], kAlphaRefConstants[2], kAlphaRefConstants[2]},
    {kAlphaRefConstants[3], kAlphaRefConstants[3], kAlphaRefConstants[3], kAlphaRefConstants[3]}};

/// reverse_bits32 of each 32-bit lane: the bytes in reverse order, then in
/// each byte its two nibbles reversed and swapped (a 16-entry table each).
inline __m128i reverse_bits32x4(__m128i x) {
  const __m128i byte_rev = _mm_setr_epi8(3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12);
  const __m128i rev_low = _mm_setr_epi8(0, 8, 4, 12, 2, 10, 6, 14, 1, 9, 5, 13, 3, 11, 7, 15);
  const __m128i rev_high = _mm_setr_epi8(0, -128, 64, -64, 32, -96, 96, -32, 16, -112, 80, -48, 48, -80, 112, -16);
  const __m128i nibble = _mm_set1_epi8(0x0F);
  x = _mm_shuffle_epi8(x, byte_rev);
  return _mm_or_si128(_mm_shuffle_epi8(rev_high, _mm_and_si128(x, nibble)),
                      _mm_shuffle_epi8(rev_low, _mm_and_si128(_mm_srli_epi16(x, 4), nibble)));
}

/// Stores the first n of x's four lanes to out (n >= 1; out holds n).
inline void store_first(uint32_t* out, __m128i x, int n) {
  if (n >= 4) {
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out), x);
    return;
  }
  if (n & 2) {
    _mm_storel_epi64(reinterpret_cast<__m128i*>(out), x);
    x = _mm_srli_si128(x, 8);
    out += 2;
  }
  if (n & 1) *out = static_cast<uint32_t>(_mm_cvtsi128_si32(x));
}
}  // namespace alpha_ref_detail
#endif

/// calc_alpha_ref for the sample indices first, first + 1, ... (wrapping at
/// 2^32 as the single calls do), count of them, of one pixel and surface:
/// the same values, with the per-pixel work done once (LK Figure 7 line 11
/// over a fragment's sorted samples).
inline void calc_alpha_refs(uint32_t first, int count, uint64_t pixel_id, uint32_t surface_id, uint32_t spp,
                            int hash_bits, uint32_t* out) {
  const uint64_t mask = low_mask(hash_bits);
  const uint32_t m = static_cast<uint32_t>(mask);
  const uint64_t pixel_base = pixel_id * uint64_t{spp};
  const int shift = 32 - hash_bits;
  int j = 0;
#if defined(__SSE4_1__) && defined(__SSSE3__)
  // Four indices at a time, lane by lane the 32-bit operations of the loop
  // below. The index's low 32 bits are those of first + j + pixel_base
  // modulo 2^32 (mask keeps at most 32), so 32-bit lanes wrap as it does.
  if (count >= 2) {
    using alpha_ref_detail::reverse_bits32x4;
    using alpha_ref_detail::store_first;
    const __m128i sid = _mm_set1_epi32(static_cast<int>(surface_id)), step = _mm_set1_epi32(4);
    __m128i index = _mm_add_epi32(_mm_set1_epi32(static_cast<int>(first + static_cast<uint32_t>(pixel_base))),
                                  _mm_setr_epi32(0, 1, 2, 3));
    if (hash_bits == 32) {  // the paper's datapath: no mask, no shift
      const __m128i* c = reinterpret_cast<const __m128i*>(alpha_ref_detail::kConstantsX4);
      for (; j < count; j += 4, index = _mm_add_epi32(index, step)) {
        __m128i x = _mm_add_epi32(reverse_bits32x4(index), sid);
        x = _mm_xor_si128(x, _mm_mullo_epi32(x, _mm_load_si128(c)));
        x = _mm_xor_si128(x, _mm_mullo_epi32(x, _mm_load_si128(c + 1)));
        x = _mm_xor_si128(x, _mm_mullo_epi32(x, _mm_load_si128(c + 2)));
        x = _mm_xor_si128(x, _mm_mullo_epi32(x, _mm_load_si128(c + 3)));
        store_first(out + j, x, count - j);
      }
    } else {
      const __m128i mv = _mm_set1_epi32(static_cast<int>(m)), sh = _mm_cvtsi32_si128(shift);
      const __m128i c0 = _mm_set1_epi32(static_cast<int>(kAlphaRefConstants[0] & m)),
                    c1 = _mm_set1_epi32(static_cast<int>(kAlphaRefConstants[1] & m)),
                    c2 = _mm_set1_epi32(static_cast<int>(kAlphaRefConstants[2] & m)),
                    c3 = _mm_set1_epi32(static_cast<int>(kAlphaRefConstants[3] & m));
      for (; j < count; j += 4, index = _mm_add_epi32(index, step)) {
        __m128i x = _mm_srl_epi32(reverse_bits32x4(_mm_and_si128(index, mv)), sh);
        x = _mm_and_si128(_mm_add_epi32(x, sid), mv);
        x = _mm_and_si128(_mm_xor_si128(x, _mm_mullo_epi32(x, c0)), mv);
        x = _mm_and_si128(_mm_xor_si128(x, _mm_mullo_epi32(x, c1)), mv);
        x = _mm_and_si128(_mm_xor_si128(x, _mm_mullo_epi32(x, c2)), mv);
        x = _mm_and_si128(_mm_xor_si128(x, _mm_mullo_epi32(x, c3)), mv);
        store_first(out + j, x, count - j);
      }
    }
    return;
  }
#endif
  uint32_t c[4];
  for (int r = 0; r < 4; ++r) c[r] = kAlphaRefConstants[r] & m;
  for (; j < count; ++j) {
    const uint32_t index = static_cast<uint32_t>((uint64_t{first + uint32_t(j)} + pixel_base) & mask);
    uint32_t x = reverse_bits32(index & m) >> shift;
    x = (x + surface_id) & m;
    for (int r = 0; r < 4; ++r) x = (x ^ (x * c[r])) & m;
    out[j] = x;
  }
}

}  // namespace ropsim
