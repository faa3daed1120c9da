// CalcAlphaRef of Laine & Karras 2011, Figure 4: a scrambled radical-inverse
// opacity reference value per sample. The default 32-bit datapath is the
// paper's; hash_bits narrows it for what-if studies (docs/numerics.md).
#pragma once
#include <cstdint>

#include "bits.h"
#include "numerics.h"

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
  uint32_t c[4];
  for (int r = 0; r < 4; ++r) c[r] = kAlphaRefConstants[r] & m;
  for (int j = 0; j < count; ++j) {
    const uint32_t index = static_cast<uint32_t>((uint64_t{first + uint32_t(j)} + pixel_base) & mask);
    uint32_t x = reverse_bits32(index & m) >> shift;
    x = (x + surface_id) & m;
    for (int r = 0; r < 4; ++r) x = (x ^ (x * c[r])) & m;
    out[j] = x;
  }
}

}  // namespace ropsim
