// Opacity format and the opacity test (docs/numerics.md "Opacity").
#pragma once
#include <cmath>
#include <cstdint>

namespace ropsim {

/// Fixed-point opacity A = round_half_even(alpha * 2^bits), alpha in [0, 1].
/// alpha is binary32, so alpha * 2^bits is exact in binary64 and the rounding
/// is the only approximation. A is in [0, 2^bits]: A = 2^bits means "always".
inline uint64_t alpha_to_fixed(float alpha, int bits) {
  if (!(alpha > 0.0f)) return 0;  // 0, -0 (NaN is rejected by the trace reader)
  if (alpha >= 1.0f) return uint64_t{1} << bits;
  const double scaled = static_cast<double>(alpha) * static_cast<double>(uint64_t{1} << bits);  // exact
  return static_cast<uint64_t>(std::nearbyint(scaled));  // default rounding: half-even
}

/// The opacity test "s.opacity > ref" of LK Figure 7, line 12, in exact integer
/// arithmetic: A / 2^alpha_bits > ref / 2^hash_bits.
/// alpha = 1 (A = 2^alpha_bits) always passes, alpha = 0 never passes, and
/// P(pass) = A / 2^alpha_bits exactly for a uniformly distributed ref.
inline bool opacity_passes(uint64_t a_fixed, int alpha_bits, uint32_t ref, int hash_bits) {
  if (alpha_bits >= hash_bits) return a_fixed > (uint64_t{ref} << (alpha_bits - hash_bits));
  return (a_fixed << (hash_bits - alpha_bits)) > uint64_t{ref};
}

}  // namespace ropsim
