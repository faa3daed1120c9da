// Depth format, per-sample depth from a plane, and the depth-test rule
// (docs/numerics.md "Depth").
#pragma once
#include <cmath>
#include <cstdint>
#include <cstring>

namespace ropsim {

/// Depth is IEEE binary32 in [0, 1], 0 = near. -0 is canonicalised to +0, so the
/// bit pattern of a stored depth orders like its value.
inline float canonical_depth(float z) {
  if (!(z > 0.0f)) return 0.0f;  // also maps -0 to +0
  if (z > 1.0f) return 1.0f;
  return z;
}

inline uint32_t depth_bits(float z) {
  uint32_t b;
  std::memcpy(&b, &z, sizeof b);
  return b;
}

/// Sample offset from the pixel centre, from a position stored in 1/256 pixel
/// units from the pixel's top-left corner. Exact in binary32.
inline float sample_offset(uint8_t pos) { return (static_cast<float>(pos) - 128.0f) / 256.0f; }

/// Depth of one sample from a fragment's plane: z0 at the pixel centre plus the
/// per-pixel gradients times the sample offset, evaluated in binary64 in this
/// order -- (z0 + dzdx*ox) + dzdy*oy -- rounded once to binary32, then clamped
/// to [0, 1]. The products are exact in binary64 (24-bit x 9-bit significands)
/// and each IEEE-754 operation is correctly rounded, so every conforming
/// implementation (no x87 extended precision, no contraction into FMA) gets
/// the same bits.
inline float plane_depth(float z0, float dzdx, float dzdy, float ox, float oy) {
  const double x = double(z0) + double(dzdx) * double(ox);
  return canonical_depth(static_cast<float>(x + double(dzdy) * double(oy)));
}

/// Calls f(i, z) for each sample i of mask, in index order, with the
/// fragment's depth z there: from its plane (plane_depth with the sample's
/// offsets ox[i], oy[i]) or from its per-sample depths (per_sample[i],
/// canonicalised). The one evaluation loop of every model and tool.
template <class F>
inline void for_each_sample_depth(uint64_t mask, bool plane, float z0, float dzdx, float dzdy, const float* ox,
                                  const float* oy, const float* per_sample, F&& f) {
  if (plane) {
    for (; mask; mask &= mask - 1) {
      const int i = __builtin_ctzll(mask);
      f(i, plane_depth(z0, dzdx, dzdy, ox[i], oy[i]));
    }
  } else {
    for (; mask; mask &= mask - 1) {
      const int i = __builtin_ctzll(mask);
      f(i, canonical_depth(per_sample[i]));
    }
  }
}

/// LK Figure 7 line 2: a sample is removed when s.z > stored; ties pass
/// (LESS_EQUAL), so a later fragment at equal depth wins.
inline bool depth_passes(float z, float stored) { return z <= stored; }  // no NaN reaches here

}  // namespace ropsim
