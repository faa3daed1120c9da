// Render-target formats and the blend operations of the ROP's blend unit:
// the one definition of how a blended value is read from and written to a
// per-sample render target, used by the golden model and the SystemC blend
// unit alike (docs/numerics.md "Blending"). A blend decodes the stored
// channels to binary32, combines them with the source in binary32 and
// encodes the result back with round-to-nearest-even.
#pragma once
#include <cstdint>
#include <cstring>

#include "rtl_models/algo/half.h"

namespace ropsim {

/// The storage format of a render target: 1 or 4 channels of binary16 or
/// binary32.
enum class TargetFormat : uint8_t { kR16F, kR32F, kRGBA16F, kRGBA32F };

inline const char* to_string(TargetFormat f) {
  switch (f) {
    case TargetFormat::kR16F:
      return "r16f";
    case TargetFormat::kR32F:
      return "r32f";
    case TargetFormat::kRGBA16F:
      return "rgba16f";
    case TargetFormat::kRGBA32F:
      return "rgba32f";
  }
  return "?";
}
inline constexpr int channels(TargetFormat f) { return f == TargetFormat::kR16F || f == TargetFormat::kR32F ? 1 : 4; }
inline constexpr bool is_half(TargetFormat f) { return f == TargetFormat::kR16F || f == TargetFormat::kRGBA16F; }
/// Bytes of one sample of a target in this format.
inline constexpr uint32_t sample_bytes(TargetFormat f) { return uint32_t(channels(f)) * (is_half(f) ? 2u : 4u); }

/// The formats of the two blend targets: the transmittance target (one
/// channel, multiplicative: the product of (1 - alpha), total alpha's
/// complement and wboit's revealage) and the accumulation target (RGBA,
/// additive: depth-based accumulation and wboit's weighted sum).
struct BlendFormats {
  TargetFormat transmittance = TargetFormat::kR16F;
  TargetFormat accum = TargetFormat::kRGBA16F;
};
inline bool operator==(const BlendFormats& a, const BlendFormats& b) {
  return a.transmittance == b.transmittance && a.accum == b.accum;
}

/// Channel c of one stored sample, as binary32.
inline float target_load(TargetFormat f, const uint8_t* p, int c) {
  if (is_half(f)) {
    uint16_t h;
    std::memcpy(&h, p + 2 * c, 2);
    return half_to_float(h);
  }
  float v;
  std::memcpy(&v, p + 4 * c, 4);
  return v;
}
/// Stores v into channel c of one sample (binary16: round to nearest even).
inline void target_store(TargetFormat f, uint8_t* p, int c, float v) {
  if (is_half(f)) {
    const uint16_t h = float_to_half(v);
    std::memcpy(p + 2 * c, &h, 2);
  } else {
    std::memcpy(p + 4 * c, &v, 4);
  }
}
/// Fills one sample with v in every channel (the clear value).
inline void target_clear(TargetFormat f, uint8_t* p, float v) {
  for (int c = 0; c < channels(f); ++c) target_store(f, p, c, v);
}

/// Multiplicative blend: dst = dst * factor in every channel.
inline void blend_multiply(TargetFormat f, uint8_t* dst, float factor) {
  for (int c = 0; c < channels(f); ++c) target_store(f, dst, c, target_load(f, dst, c) * factor);
}
/// Additive blend: dst = dst + src, channel by channel (src has channels(f) values).
inline void blend_add(TargetFormat f, uint8_t* dst, const float* src) {
  for (int c = 0; c < channels(f); ++c) target_store(f, dst, c, target_load(f, dst, c) + src[c]);
}

/// The same two blends for a format known at compile time (the blend stage
/// dispatches once per fragment, not per channel); identical results. The
/// four-channel formats run their channels as the four lanes of one SSE
/// register where there is SSE2: the same binary32 product or sum per
/// channel, and the same binary16 conversions (half4_to_float4,
/// float4_to_half4), so the same bits.
template <TargetFormat F>
inline void blend_multiply_as(uint8_t* dst, float factor) {
#if defined(__SSE2__)
  if constexpr (F == TargetFormat::kRGBA16F) {
    store_half4(dst, float4_to_half4(_mm_mul_ps(half4_to_float4(load_half4(dst)), _mm_set1_ps(factor))));
    return;
  } else if constexpr (F == TargetFormat::kRGBA32F) {
    _mm_storeu_ps(reinterpret_cast<float*>(dst),
                  _mm_mul_ps(_mm_loadu_ps(reinterpret_cast<const float*>(dst)), _mm_set1_ps(factor)));
    return;
  }
#endif
  for (int c = 0; c < channels(F); ++c) target_store(F, dst, c, target_load(F, dst, c) * factor);
}
template <TargetFormat F>
inline void blend_add_as(uint8_t* dst, const float* src) {
#if defined(__SSE2__)
  if constexpr (F == TargetFormat::kRGBA16F) {
    store_half4(dst, float4_to_half4(_mm_add_ps(half4_to_float4(load_half4(dst)), _mm_loadu_ps(src))));
    return;
  } else if constexpr (F == TargetFormat::kRGBA32F) {
    _mm_storeu_ps(reinterpret_cast<float*>(dst),
                  _mm_add_ps(_mm_loadu_ps(reinterpret_cast<const float*>(dst)), _mm_loadu_ps(src)));
    return;
  }
#endif
  for (int c = 0; c < channels(F); ++c) target_store(F, dst, c, target_load(F, dst, c) + src[c]);
}

/// blend_multiply_as<F>(dst + i * sample_bytes(F), factor) for each sample i
/// of mask, dst the first of a pixel's spp samples. A binary16 target of
/// four samples or more (where there is SSE2) runs four samples at a time,
/// each group's unchosen samples stored back unchanged; identical results.
template <TargetFormat F>
inline void blend_multiply_samples(uint8_t* dst, uint64_t mask, int spp, float factor) {
#if defined(__SSE2__)
  if constexpr (F == TargetFormat::kR16F) {
    if (spp >= 4) {  // a power of two: whole groups of four, none past the pixel
      const __m128i bit = _mm_setr_epi32(1, 2, 4, 8);
      const __m128 k = _mm_set1_ps(factor);
      for (; mask; mask &= ~(uint64_t{0xF} << (__builtin_ctzll(mask) & ~3))) {
        const int g = __builtin_ctzll(mask) & ~3;  // the group of the lowest chosen sample
        uint8_t* p = dst + 2 * g;
        const __m128i old = load_half4(p);
        const __m128i now = float4_to_half4(_mm_mul_ps(half4_to_float4(old), k));
        const __m128i pick = _mm_cmpeq_epi32(_mm_and_si128(_mm_set1_epi32(int(mask >> g & 0xF)), bit), bit);
        store_half4(p, _mm_or_si128(_mm_and_si128(pick, now), _mm_andnot_si128(pick, old)));
      }
      return;
    }
  }
#endif
  for (; mask; mask &= mask - 1) blend_multiply_as<F>(dst + size_t(__builtin_ctzll(mask)) * sample_bytes(F), factor);
}

/// Weighted blended OIT's weight (McGuire & Bavoil 2013, Eq. 10): alpha
/// times max(10^-2, 3 10^3 (1 - z)^3), z the fragment's depth-buffer depth
/// in [0, 1]; nearer fragments weigh more, at most 3000 alpha.
inline float wboit_weight(float z, float alpha) {
  const float d = 1.0f - z;
  const float w = 3.0e3f * d * d * d;
  return alpha * (w > 1.0e-2f ? w : 1.0e-2f);
}

/// wboit's clamp of the accumulated weight in its composite (Eq. 6 with the
/// paper's clamp [10^-4, 5 10^4]).
inline float wboit_clamp_weight(float a) { return a < 1.0e-4f ? 1.0e-4f : a > 5.0e4f ? 5.0e4f : a; }

}  // namespace ropsim
