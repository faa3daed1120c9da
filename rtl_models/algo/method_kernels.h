// Per-fragment decisions of the comparison methods, shared by the golden model
// and the SystemC units: alpha-to-coverage's sample mask and Enderton et al.'s
// random sample count and picks. No SystemC, no state.
#pragma once
#include <algorithm>
#include <array>
#include <cstdint>

#include "numerics.h"
#include "random_hash.h"

namespace ropsim {

/// a2c: prefix[k] is the mask of the first k samples of the bit-reversed
/// sample order, so any prefix is spread over the pixel.
inline std::array<uint64_t, 65> a2c_prefix_table(int spp) {
  std::array<uint64_t, 65> t{};
  const int m = log2_floor(unsigned(spp));
  for (int k = 1; k <= spp; ++k)
    t[size_t(k)] = t[size_t(k - 1)] | (uint64_t{1} << reverse_low_bits(uint32_t(k - 1), m));
  return t;
}

/// a2c: 4x4 ordered-dither thresholds (Bayer), in 1/16 units.
constexpr uint32_t kA2cBayer4[16] = {0, 8, 2, 10, 12, 4, 14, 6, 3, 11, 1, 9, 15, 7, 13, 5};

/// a2c: k = floor(alpha * spp + dither) samples, the dither being the pixel's
/// Bayer threshold (d + 1/2) / 16; the same alpha always gives the same samples
/// in a pixel (static assignment). a_fixed is alpha_to_fixed(alpha, alpha_bits).
inline uint32_t a2c_sample_count(uint64_t a_fixed, int alpha_bits, int spp, uint32_t x, uint32_t y) {
  const uint64_t a32 = a_fixed << (32 - alpha_bits);
  const uint64_t dither = uint64_t(2 * kA2cBayer4[(y & 3u) * 4 + (x & 3u)] + 1) << 27;
  return uint32_t(std::min<uint64_t>(uint64_t(spp), (a32 * uint64_t(spp) + dither) >> 32));
}

/// Enderton et al. 2010 with the depth test first (as LK compare against):
/// R = floor(alpha * m + xi) of the m depth survivors are written.
inline uint32_t enderton_count(uint64_t a_fixed, int alpha_bits, uint32_t m, uint64_t key) {
  const uint64_t a32 = a_fixed << (32 - alpha_bits);
  return uint32_t((a32 * uint64_t(m) + fragment_random(key, 0)) >> 32);
}

/// Enderton: the R written samples are a partial Fisher-Yates shuffle of the
/// survivor list[0..m) with hashed choices; afterwards list[0..R) are the
/// chosen sample ids, in choice order.
inline void enderton_pick(int* list, uint32_t m, uint32_t r, uint64_t key) {
  for (uint32_t j = 0; j < r; ++j) {
    const uint32_t pick = j + uint32_t((uint64_t(fragment_random(key, j + 1)) * (m - j)) >> 32);
    std::swap(list[j], list[pick]);
  }
}

}  // namespace ropsim
