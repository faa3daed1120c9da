// Depth format, per-sample depth from a plane, and the depth-test rule
// (docs/numerics.md "Depth").
#pragma once
#include <cmath>
#include <cstdint>
#include <cstring>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

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

#if defined(__SSE2__)
/// for_each_sample_depth over every sample 0 .. spp - 1 (spp a multiple of
/// 4), four at a time, with the depth test folded in: writes each sample's
/// depth to z[i] and returns the mask of the samples that pass depth_passes
/// against stored[i]. The same binary64 products and sums in the same order,
/// the same rounding to binary32 and canonical_depth as max(z, 0) then
/// min(., 1) (MAXPS returns its second operand, 0, for a NaN, -0 or negative
/// z): bit for bit the scalar loop's depths.
inline uint64_t sample_depths_and_test(int spp, bool plane, float z0, float dzdx, float dzdy, const float* ox,
                                       const float* oy, const float* per_sample, const float* stored, float* z) {
  const __m128 zero = _mm_setzero_ps(), one = _mm_set1_ps(1.0f);
  const __m128d z0d = _mm_set1_pd(double(z0)), dxd = _mm_set1_pd(double(dzdx)), dyd = _mm_set1_pd(double(dzdy));
  uint64_t pass = 0;
  for (int i = 0; i < spp; i += 4) {
    __m128 zi;
    if (plane) {
      const __m128 x4 = _mm_loadu_ps(ox + i), y4 = _mm_loadu_ps(oy + i);
      const __m128d xl = _mm_cvtps_pd(x4), xh = _mm_cvtps_pd(_mm_movehl_ps(x4, x4));
      const __m128d yl = _mm_cvtps_pd(y4), yh = _mm_cvtps_pd(_mm_movehl_ps(y4, y4));
      const __m128d dl = _mm_add_pd(_mm_add_pd(z0d, _mm_mul_pd(dxd, xl)), _mm_mul_pd(dyd, yl));
      const __m128d dh = _mm_add_pd(_mm_add_pd(z0d, _mm_mul_pd(dxd, xh)), _mm_mul_pd(dyd, yh));
      zi = _mm_movelh_ps(_mm_cvtpd_ps(dl), _mm_cvtpd_ps(dh));
    } else {
      zi = _mm_loadu_ps(per_sample + i);
    }
    zi = _mm_min_ps(_mm_max_ps(zi, zero), one);
    _mm_storeu_ps(z + i, zi);
    pass |= uint64_t(_mm_movemask_ps(_mm_cmple_ps(zi, _mm_loadu_ps(stored + i)))) << i;
  }
  return pass;
}
#endif

}  // namespace ropsim
