// Per-fragment decisions of the comparison methods, shared by the golden model
// and the SystemC units: alpha-to-coverage's sample mask, Enderton et al.'s
// random sample count and picks, and the hashed alpha test's and hashed
// alpha-to-coverage's thresholds. No SystemC, no state.
#pragma once
#include <algorithm>
#include <array>
#include <cstdint>

#include "rtl_models/algo/numerics.h"
#include "rtl_models/algo/opacity.h"
#include "rtl_models/algo/random_hash.h"

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

/// hashed (Wyman & McGuire 2017, §4): the alpha test against one hashed
/// threshold chi per fragment; every covered sample is kept if alpha > chi, so
/// P(kept) = alpha. chi is the fragment's random lane 0.
inline bool hashed_alpha_passes(uint64_t a_fixed, int alpha_bits, uint64_t key) {
  return opacity_passes(a_fixed, alpha_bits, fragment_random(key, 0), 32);
}

/// hashed-a2c (Wyman & McGuire 2017, §8, Eq. 9): a fragment's offset
/// alpha_o = floor(n xi1), odd increment alpha_+ = 2 floor(0.5 n xi2) + 1 and
/// jitter chi, from its random lanes 0, 1 and 2. One chi per fragment (the
/// paper allows chi_i = chi_j): then the samples kept are exactly
/// floor(alpha n + 1 - chi) of them, the fewest a stratified choice can vary.
struct HashedA2cPattern {
  uint32_t offset;     ///< alpha_o in [0, n)
  uint32_t increment;  ///< alpha_+, odd, in [1, n)
  uint32_t chi;        ///< the jitter, in 2^-32 units
};

inline HashedA2cPattern hashed_a2c_pattern(uint64_t key, uint32_t n) {
  HashedA2cPattern p;
  p.offset = uint32_t((uint64_t{fragment_random(key, 0)} * n) >> 32);
  p.increment = 2 * uint32_t((uint64_t{fragment_random(key, 1)} * (n / 2)) >> 32) + 1;
  p.chi = fragment_random(key, 2);
  return p;
}

/// Sample i's threshold (chi + ((alpha_o + i alpha_+) mod n)) / n as the
/// integer threshold * n * 2^32 (exact). n is a power of two, so the odd
/// increment makes i -> stratum a permutation: one threshold in each 1/n.
inline uint64_t hashed_a2c_threshold(const HashedA2cPattern& p, uint32_t n, uint32_t i) {
  return uint64_t{(p.offset + i * p.increment) & (n - 1)} << 32 | p.chi;
}

/// The samples of [0, n) whose threshold alpha exceeds (alpha > threshold, as
/// the opacity test: alpha 0 keeps none, alpha 1 keeps all).
inline uint64_t hashed_a2c_mask(uint64_t a_fixed, int alpha_bits, uint32_t n, uint64_t key) {
  const HashedA2cPattern p = hashed_a2c_pattern(key, n);
  const uint64_t a_n = (a_fixed << (32 - alpha_bits)) * n;  // alpha n 2^32, at most 2^38
  uint64_t mask = 0;
  for (uint32_t i = 0; i < n; ++i) mask |= uint64_t{a_n > hashed_a2c_threshold(p, n, i)} << i;
  return mask;
}

}  // namespace ropsim
