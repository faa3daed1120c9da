// The blend stage's definitions: the transmittance and accumulation blends.
// Included by functional_rop_stages.h only, which defines ROPSIM_DISPATCH.
#pragma once

namespace ropsim {

namespace detail {
/// The blend stage's multiplicative blend for one transmittance format: each
/// survivor's transmittance times (1 - alpha).
template <TargetFormat TF>
inline void multiply_survivors(const FragWork& w, int spp) {
  blend_multiply_samples<TF>(w.px.trans, w.survivors, spp, 1.0f - w.f->alpha);
}

/// The blend stage's additive blend for one accumulation format: accumulate
/// adds (alpha c, alpha) to each survivor; wboit (weighted) the same times
/// its weight w(z, alpha). Everything per fragment is read once, before the
/// loop (the targets are bytes, which the compiler must assume alias it).
template <TargetFormat AF, bool kWeighted>
inline void add_survivors(const FragWork& w, const std::array<float, 3>& rgb) {
  constexpr uint32_t ab = sample_bytes(AF);
  const Fragment& f = *w.f;
  const float a = f.alpha, r = rgb[0], g = rgb[1], b = rgb[2];
  uint8_t* const accum = w.px.accum;
  const float* const z = w.z;
  if constexpr (kWeighted) {
    for (uint64_t s = w.survivors; s; s &= s - 1) {
      const int i = __builtin_ctzll(s);
      const float k = a * wboit_weight(z[i], a);
      const float src[4] = {k * r, k * g, k * b, k};
      blend_add_as<AF>(accum + size_t(i) * ab, src);
    }
  } else {
    const float src[4] = {a * r, a * g, a * b, a};
    for (uint64_t s = w.survivors; s; s &= s - 1) blend_add_as<AF>(accum + size_t(__builtin_ctzll(s)) * ab, src);
  }
}
}  // namespace detail

inline uint32_t BlendStage::run(FragWork& w) {
  const BlendFormats& fmt = s_.cfg.formats;
  const PassKind pass = s_.pass;
  if (pass == PassKind::kFramebuffer) {
    // blend: each survivor's framebuffer sample (RGBA binary32 in the store,
    // read, blended, written) and, as the draw's depth mask says, its depth.
    const DrawState& d = *w.draw;
    const Fragment& f = *w.f;
    const float src[4] = {f.rgb[0], f.rgb[1], f.rgb[2], f.alpha};
    const bool zw = draw_writes_depth(d);
    for (uint64_t s = w.survivors; s; s &= s - 1) {
      const int i = __builtin_ctzll(s);
      uint8_t* p = w.px.accum + size_t(i) * 16;
      float dst[4];
      std::memcpy(dst, p, sizeof dst);
      framebuffer_blend(d, src, dst);
      std::memcpy(p, dst, sizeof dst);
      if (zw) w.px.depth[i] = w.z[i];
    }
    const uint32_t n = w.m;
    w.written = w.survivors;
    w.depth_written = zw ? w.survivors : 0;
    record_plane_keys(w);
    c_.samples_blended += n;
    const uint64_t fb = s_.bytes.of(Buffer::kAccum);                     // the framebuffer's sample in memory
    if (draw_reads_colour(d)) c_.target_bytes_read += uint64_t(n) * fb;  // an opaque draw replaces it unread
    c_.target_bytes_written += uint64_t(n) * fb;
    const uint32_t nz = zw ? n : 0;
    c_.samples_written += nz;
    c_.depth_bytes_written += kDepthSampleBytes * nz;
    return n;
  }
  const bool trans = pass == PassKind::kTotalAlpha || pass == PassKind::kWboit;
  const bool accum = pass == PassKind::kAccumulate || pass == PassKind::kWboit;
  // The two targets are separate buffers: blending one, then the other, is
  // blending both sample by sample.
  if (trans) {
    if (fmt.transmittance == TargetFormat::kR16F)
      detail::multiply_survivors<TargetFormat::kR16F>(w, s_.spp);
    else
      detail::multiply_survivors<TargetFormat::kR32F>(w, s_.spp);
  }
  if (accum) {
    const bool half_a = fmt.accum == TargetFormat::kRGBA16F, weighted = pass == PassKind::kWboit;
    // A frame of draw states: the src-over draw's straight colour (transparent_rgb).
    const std::array<float, 3> rgb = s_.draw_states ? transparent_rgb(*w.draw, w.f->rgb, w.f->alpha) : w.f->rgb;
    if (half_a && weighted)
      detail::add_survivors<TargetFormat::kRGBA16F, true>(w, rgb);
    else if (half_a)
      detail::add_survivors<TargetFormat::kRGBA16F, false>(w, rgb);
    else if (weighted)
      detail::add_survivors<TargetFormat::kRGBA32F, true>(w, rgb);
    else
      detail::add_survivors<TargetFormat::kRGBA32F, false>(w, rgb);
  }
  const uint32_t n = w.m;
  c_.samples_blended += n;
  const uint64_t bytes =
      uint64_t(n) * ((trans ? sample_bytes(fmt.transmittance) : 0) + (accum ? sample_bytes(fmt.accum) : 0));
  c_.target_bytes_read += bytes;
  c_.target_bytes_written += bytes;
  w.written = w.survivors;
  return n;
}

}  // namespace ropsim
