// The `blend` method's rule (docs/methods.md "blend"): how one fragment's
// sample meets the framebuffer under its draw's state, as GL's per-fragment
// operations define it (OpenGL 4.6 core, 14.9 depth test, 17.3.6 blending,
// 17.3.7 sRGB conversion, 17.4.2 colour mask). The one definition: the golden
// model's blend stage and the cycle model's blend unit both call it.
//
// A framebuffer sample holds RGBA as four binary32 values in the target's
// own encoding:
//   unorm8  q / 255, q the stored byte; a blend runs in 8-bit fixed point as
//           a fixed-function blender does (llvmpipe's too): source, constant
//           and factors become bytes, each product x * y / 255 rounds to the
//           nearest byte, and the equation saturates to [0, 255];
//   srgb8   q / 255, q the stored sRGB code of R, G, B (read back to linear
//           through the IEC 61966-2-1 curve, blended in linear, encoded and
//           rounded to a byte on store) and the alpha byte as unorm8;
//   float   the value itself (no clamping, no rounding).
// So a run's image holds the target's values as the framebuffer stores them.
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

#include "rtl_models/algo/half.h"
#include "traces/format/draw_state.h"

namespace ropsim {

/// Does a fragment's depth z pass function f against the stored depth?
inline bool depth_func_passes(DepthFunc f, float z, float stored) {
  switch (f) {
    case DepthFunc::kNever:
      return false;
    case DepthFunc::kLess:
      return z < stored;
    case DepthFunc::kEqual:
      return z == stored;
    case DepthFunc::kLequal:
      return z <= stored;
    case DepthFunc::kGreater:
      return z > stored;
    case DepthFunc::kNotequal:
      return z != stored;
    case DepthFunc::kGequal:
      return z >= stored;
    case DepthFunc::kAlways:
      return true;
  }
  return false;
}

/// Does a sample that passed the draw's depth test get its depth written?
/// GL writes depth only with the test enabled (a disabled test also disables
/// the write) and the depth mask on.
inline bool draw_writes_depth(const DrawState& d) { return d.depth_test && d.depth_write; }

namespace fb {
inline float clamp01(float v) { return v < 0.0f ? 0.0f : v > 1.0f ? 1.0f : v; }  // NaN -> 1 (neither compare holds)
/// The byte an 8-bit normalised channel stores for v (clamped, round to nearest).
inline uint32_t unorm8_code(float v) { return uint32_t(clamp01(v) * 255.0f + 0.5f); }
inline float unorm8_value(uint32_t q) { return float(q) / 255.0f; }
/// IEC 61966-2-1 linear -> sRGB, on [0, 1].
inline float srgb_encode(float v) {
  v = clamp01(v);
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}
/// sRGB code q -> linear, one table of the 256 codes (IEC 61966-2-1).
inline float srgb_decode_code(uint32_t q) {
  static const std::array<float, 256> table = [] {
    std::array<float, 256> t{};
    for (uint32_t i = 0; i < 256; ++i) {
      const float c = float(i) / 255.0f;
      t[i] = c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
    }
    return t;
  }();
  return table[q > 255 ? 255 : q];
}
inline uint32_t code_of(float stored) { return uint32_t(clamp01(stored) * 255.0f + 0.5f); }
}  // namespace fb

/// The blend's working value of stored channel c (0..3) of encoding e:
/// linear for sRGB colour, the stored value otherwise.
inline float framebuffer_read(TargetEncoding e, int c, float stored) {
  if (e == TargetEncoding::kSrgb8 && c < 3) return fb::srgb_decode_code(fb::code_of(stored));
  return stored;
}
/// What encoding e stores for working value v in channel c (0..3).
inline float framebuffer_store(TargetEncoding e, int c, float v) {
  switch (e) {
    case TargetEncoding::kUnorm8:
      return fb::unorm8_value(fb::unorm8_code(v));
    case TargetEncoding::kSrgb8:
      return fb::unorm8_value(fb::unorm8_code(c < 3 ? fb::srgb_encode(v) : v));
    case TargetEncoding::kFloat:
      break;
  }
  return v;
}

namespace fb {
/// Blend factor f for channel c (0..3; 3 is alpha) of source s, destination d
/// and constant k (GL 4.6 table 17.2).
inline float factor(BlendFactor f, int c, const float* s, const float* d, const float* k) {
  switch (f) {
    case BlendFactor::kZero:
      return 0.0f;
    case BlendFactor::kOne:
      return 1.0f;
    case BlendFactor::kSrcColor:
      return s[c];
    case BlendFactor::kOneMinusSrcColor:
      return 1.0f - s[c];
    case BlendFactor::kDstColor:
      return d[c];
    case BlendFactor::kOneMinusDstColor:
      return 1.0f - d[c];
    case BlendFactor::kSrcAlpha:
      return s[3];
    case BlendFactor::kOneMinusSrcAlpha:
      return 1.0f - s[3];
    case BlendFactor::kDstAlpha:
      return d[3];
    case BlendFactor::kOneMinusDstAlpha:
      return 1.0f - d[3];
    case BlendFactor::kConstantColor:
      return k[c];
    case BlendFactor::kOneMinusConstantColor:
      return 1.0f - k[c];
    case BlendFactor::kConstantAlpha:
      return k[3];
    case BlendFactor::kOneMinusConstantAlpha:
      return 1.0f - k[3];
    case BlendFactor::kSrcAlphaSaturate:
      return c == 3 ? 1.0f : std::min(s[3], 1.0f - d[3]);
  }
  return 0.0f;
}
/// Equation e of source s and destination d with their factors (table 17.1);
/// MIN and MAX ignore the factors.
inline float combine(BlendEquation e, float s, float fs, float d, float fd) {
  switch (e) {
    case BlendEquation::kAdd:
      return s * fs + d * fd;
    case BlendEquation::kSubtract:
      return s * fs - d * fd;
    case BlendEquation::kReverseSubtract:
      return d * fd - s * fs;
    case BlendEquation::kMin:
      return std::min(s, d);
    case BlendEquation::kMax:
      return std::max(s, d);
  }
  return s;
}

/// x * y / 255 of two bytes, rounded to the nearest byte (exact for every
/// pair: t + (t >> 8) >> 8 with t = x y + 128 is round(x y / 255)).
inline uint32_t mul_unorm8(uint32_t x, uint32_t y) {
  const uint32_t t = x * y + 128;
  return (t + (t >> 8)) >> 8;
}
/// Factor f of channel c as a byte, from the bytes of source s, destination d
/// and constant k (the byte of 1 - x is 255 - x).
inline uint32_t factor_unorm8(BlendFactor f, int c, const uint32_t* s, const uint32_t* d, const uint32_t* k) {
  switch (f) {
    case BlendFactor::kZero:
      return 0;
    case BlendFactor::kOne:
      return 255;
    case BlendFactor::kSrcColor:
      return s[c];
    case BlendFactor::kOneMinusSrcColor:
      return 255 - s[c];
    case BlendFactor::kDstColor:
      return d[c];
    case BlendFactor::kOneMinusDstColor:
      return 255 - d[c];
    case BlendFactor::kSrcAlpha:
      return s[3];
    case BlendFactor::kOneMinusSrcAlpha:
      return 255 - s[3];
    case BlendFactor::kDstAlpha:
      return d[3];
    case BlendFactor::kOneMinusDstAlpha:
      return 255 - d[3];
    case BlendFactor::kConstantColor:
      return k[c];
    case BlendFactor::kOneMinusConstantColor:
      return 255 - k[c];
    case BlendFactor::kConstantAlpha:
      return k[3];
    case BlendFactor::kOneMinusConstantAlpha:
      return 255 - k[3];
    case BlendFactor::kSrcAlphaSaturate:
      return c == 3 ? 255 : std::min(s[3], 255 - d[3]);
  }
  return 0;
}
/// Equation e on bytes, saturated to [0, 255]; MIN and MAX ignore the factors.
inline uint32_t combine_unorm8(BlendEquation e, uint32_t s, uint32_t fs, uint32_t d, uint32_t fd) {
  const int32_t a = int32_t(mul_unorm8(s, fs)), b = int32_t(mul_unorm8(d, fd));
  int32_t r = 0;
  switch (e) {
    case BlendEquation::kAdd:
      r = a + b;
      break;
    case BlendEquation::kSubtract:
      r = a - b;
      break;
    case BlendEquation::kReverseSubtract:
      r = b - a;
      break;
    case BlendEquation::kMin:
      return std::min(s, d);
    case BlendEquation::kMax:
      return std::max(s, d);
  }
  return uint32_t(std::clamp(r, 0, 255));
}
}  // namespace fb

/// One sample of the framebuffer (dst: its four stored channels) after a
/// fragment of colour rgba from a draw of state d passed its depth test:
/// with blending off the source replaces the destination; on, each channel is
/// the draw's equation of source and destination times their factors. A
/// fixed-point target (unorm8, srgb8) clamps the source and the constant
/// colour to [0, 1] first; unorm8 blends in 8-bit fixed point, srgb8 in
/// binary32 on linear values. Channels the colour mask leaves off keep their
/// stored value.
inline void framebuffer_blend(const DrawState& d, const float rgba[4], float dst[4]) {
  const TargetEncoding e = d.encoding;
  if (e == TargetEncoding::kUnorm8 && d.blend) {
    uint32_t s[4], t[4], k[4];
    for (int c = 0; c < 4; ++c) {
      s[c] = fb::unorm8_code(rgba[c]);
      t[c] = fb::code_of(dst[c]);
      k[c] = fb::unorm8_code(d.blend_color[size_t(c)]);
    }
    for (int c = 0; c < 4; ++c) {
      if (!(d.color_mask >> c & 1)) continue;
      const bool alpha = c == 3;
      const uint32_t q = fb::combine_unorm8(alpha ? d.eq_alpha : d.eq_rgb, s[c],
                                            fb::factor_unorm8(alpha ? d.src_alpha : d.src_rgb, c, s, t, k), t[c],
                                            fb::factor_unorm8(alpha ? d.dst_alpha : d.dst_rgb, c, s, t, k));
      dst[c] = fb::unorm8_value(q);
    }
    return;
  }
  const bool fixed = e != TargetEncoding::kFloat;
  float s[4], t[4], k[4], out[4];
  for (int c = 0; c < 4; ++c) {
    s[c] = fixed ? fb::clamp01(rgba[c]) : rgba[c];
    t[c] = framebuffer_read(e, c, dst[c]);
    k[c] = fixed ? fb::clamp01(d.blend_color[size_t(c)]) : d.blend_color[size_t(c)];
  }
  if (!d.blend) {
    for (int c = 0; c < 4; ++c) out[c] = s[c];
  } else {
    for (int c = 0; c < 3; ++c)
      out[c] = fb::combine(d.eq_rgb, s[c], fb::factor(d.src_rgb, c, s, t, k), t[c], fb::factor(d.dst_rgb, c, s, t, k));
    out[3] =
        fb::combine(d.eq_alpha, s[3], fb::factor(d.src_alpha, 3, s, t, k), t[3], fb::factor(d.dst_alpha, 3, s, t, k));
  }
  for (int c = 0; c < 4; ++c)
    if (d.color_mask >> c & 1) dst[c] = framebuffer_store(e, c, out[c]);
}

/// A framebuffer sample's clear value: the trace's clear colour (linear RGB)
/// with alpha 1, stored in encoding e.
inline std::array<float, 4> framebuffer_clear(TargetEncoding e, const std::array<float, 3>& rgb) {
  return {framebuffer_store(e, 0, rgb[0]), framebuffer_store(e, 1, rgb[1]), framebuffer_store(e, 2, rgb[2]),
          framebuffer_store(e, 3, 1.0f)};
}

/// The encoding of a frame's framebuffer: its last draw's (the table's
/// highest draw id), float for an empty table (every draw's default state).
inline TargetEncoding frame_encoding(const DrawTable& t) {
  return t.empty() ? TargetEncoding::kFloat : t.states().back().encoding;
}

/// The resolve of one pixel's spp samples (stored values, RGBA) to its image
/// value in encoding e: float averages the samples; unorm8 averages the
/// stored values and rounds to a byte; srgb8 averages in linear and encodes
/// and rounds the result (a multisample resolve into a one-sample target of
/// the same encoding). Samples summed in sample order.
inline void framebuffer_resolve_pixel(TargetEncoding e, const float* samples, int spp, float rgb[3]) {
  const float inv = 1.0f / float(spp);  // exact: spp is a power of two
  for (int c = 0; c < 3; ++c) {
    float sum = 0.0f;
    for (int i = 0; i < spp; ++i) sum += framebuffer_read(e, c, samples[4 * i + c]);
    rgb[c] = spp == 1 ? samples[c] : framebuffer_store(e, c, sum * inv);
  }
}

// ------------------------------------------------ the methods' colour buffer
//
// Every method but blend keeps one RGB binary16 colour per sample. On a
// frame of draw states (docs/methods.md "Methods on a frame of draw states")
// it holds the working value of the target's encoding (framebuffer_read) of
// what the target stores: linear light of an 8-bit code for srgb8, the code
// value for unorm8, the colour for float. Destination alpha is not kept: it
// reads as 1. In memory an 8-bit target's sample is RGBA8 (surface_bytes.h).

/// The colour a src-over draw's fragment contributes, as straight (not
/// premultiplied) colour: premultiplied draws' colour divided by alpha (0 for
/// alpha 0), clamped to [0, 1] for an 8-bit target as its blender clamps it.
inline std::array<float, 3> transparent_rgb(const DrawState& d, const std::array<float, 3>& rgb, float alpha) {
  std::array<float, 3> c = rgb;
  if (draw_kind(d) == DrawKind::kPremultipliedOver)
    for (float& v : c) v = alpha > 0.0f ? v / alpha : 0.0f;
  if (d.encoding != TargetEncoding::kFloat)
    for (float& v : c) v = fb::clamp01(v);
  return c;
}

/// The working value the colour buffer stores for straight colour rgb that
/// a method writes over a sample: the colour stored in the frame's target
/// encoding e and read back (an 8-bit target holds codes; the colour itself
/// for a float target).
inline std::array<float, 3> colour_buffer_value(TargetEncoding e, const std::array<float, 3>& rgb) {
  if (e == TargetEncoding::kFloat) return rgb;
  std::array<float, 3> v{};
  for (int c = 0; c < 3; ++c) v[size_t(c)] = framebuffer_read(e, c, framebuffer_store(e, c, rgb[size_t(c)]));
  return v;
}

/// An opaque or blended draw's fragment (colour rgba) on one stored sample
/// (rgb16: its working value, binary16): the sample stored in the target's
/// encoding, framebuffer_blend, and back to the working value. An opaque
/// draw with every colour channel on replaces it without reading it.
inline void colour_buffer_blend(const DrawState& d, const float rgba[4], uint16_t* rgb16) {
  const TargetEncoding e = d.encoding;
  float dst[4];
  for (int c = 0; c < 3; ++c) dst[c] = framebuffer_store(e, c, half_to_float(rgb16[c]));
  dst[3] = 1.0f;
  framebuffer_blend(d, rgba, dst);
  for (int c = 0; c < 3; ++c) rgb16[c] = float_to_half(framebuffer_read(e, c, dst[c]));
}

/// The colour buffer's clear value: the trace's clear colour as the frame's
/// target of encoding e stores it, as a working value (the clear colour
/// itself for a float target).
inline std::array<float, 3> colour_buffer_clear(TargetEncoding e, const std::array<float, 3>& rgb) {
  std::array<float, 3> c{};
  for (int i = 0; i < 3; ++i) c[size_t(i)] = framebuffer_read(e, i, framebuffer_store(e, i, rgb[size_t(i)]));
  return c;
}

/// Does a draw's fragment read the stored colour (a read-modify-write)?
/// Blending reads it; so does a colour mask that keeps a channel.
inline bool draw_reads_colour(const DrawState& d) {
  return draw_kind(d) != DrawKind::kOpaque || (d.color_mask & 7) != 7;
}

/// Linear light of value v of an image resolved in encoding e: an 8-bit
/// target's values are code values (their sRGB decoding, as a display shows
/// them; unorm8 stores display codes), a float target's are light.
inline float framebuffer_light(TargetEncoding e, float v) {
  return e == TargetEncoding::kFloat ? v : fb::srgb_decode_code(fb::code_of(v));
}

/// One resolved working value of a method's colour buffer (the box filter of
/// its samples) as the frame's target stores it, then as light: a resolve
/// into a one-sample target of the frame's encoding, as blend resolves.
inline float resolved_light(TargetEncoding e, float working) {
  return e == TargetEncoding::kFloat ? working : framebuffer_light(e, framebuffer_store(e, 0, working));
}

}  // namespace ropsim
