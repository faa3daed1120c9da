// The write stage's definitions: each method's write of the surviving samples, and the routed draws' writes.
// Included by functional_rop_stages.h only, which defines ROPSIM_DISPATCH.
#pragma once

namespace ropsim {

template <Method M>
inline uint32_t WriteStage::run_as(FragWork& w) {
  const Numerics& num = s_.cfg.numerics;
  [[maybe_unused]] RopObserver* const obs = s_.observer;
  // A frame of draw states: the src-over draw's straight colour (transparent_rgb).
  const uint16_t* rgb16 = s_.draw_states ? memo_.half_color(transparent_rgb(*w.draw, w.f->rgb, w.f->alpha))
                                         : memo_.half_color(w.f->rgb);  // (no copy of the colour)
  // What the colour buffer stores: on an 8-bit target the colour as the
  // target stores it (colour_buffer_value); +ac's accumulation target and
  // slab's layers keep rgb16.
  [[maybe_unused]] uint16_t stored16[3];
  [[maybe_unused]] const uint16_t* colour16 = rgb16;
  if constexpr (stochastic_writes_color(M) && M != Method::kSlab)
    if (s_.draw_states && s_.encoding != TargetEncoding::kFloat) {
      const std::array<float, 3> v = colour_buffer_value(s_.encoding, transparent_rgb(*w.draw, w.f->rgb, w.f->alpha));
      for (int c = 0; c < 3; ++c) stored16[c] = float_to_half(v[size_t(c)]);
      colour16 = stored16;
    }
  uint64_t wrote = 0;
  uint32_t examined = w.m;
  PixelRef px = w.px;
  const float* z = w.z;
  // Depth-based methods' stochastic pass stores depth only (Enderton et al.
  // 3.4). Over a pre-pass (method.h): +ac stores (c, 1) in the accumulation
  // target, leaving the colour buffer's background; +depth marks the
  // sample in the transmittance target (0).
  constexpr bool kColor = stochastic_writes_color(M);
  constexpr bool kMayAccum = stochastic_colour_in_accum(M, true), kMayMark = stochastic_marks_transmittance(M, true);
  [[maybe_unused]] const bool to_accum = kMayAccum && s_.prepass, mark = kMayMark && s_.prepass;
  [[maybe_unused]] const BlendFormats& fmt = s_.cfg.formats;
  [[maybe_unused]] float c1[4] = {0, 0, 0, 1};
  if constexpr (kMayAccum)
    if (to_accum)
      for (int c = 0; c < 3; ++c) c1[c] = half_to_float(rgb16[c]);
  [[maybe_unused]] auto write = [&](int i, float zi) {
    if constexpr (kColor) {
      if constexpr (kMayAccum) {
        if (to_accum) {
          px.depth[i] = zi;
          uint8_t* a = px.accum + size_t(i) * sample_bytes(fmt.accum);
          for (int c = 0; c < 4; ++c) target_store(fmt.accum, a, c, c1[c]);
          return;
        }
      }
      px.write_sample(i, zi, colour16);
    } else {
      px.depth[i] = zi;  // depth only
      if constexpr (kMayMark)
        if (mark) target_store(fmt.transmittance, px.trans + size_t(i) * sample_bytes(fmt.transmittance), 0, 0.0f);
    }
  };
  // A src-over draw with its depth test off writes no depth (as GL: no
  // depth writes without the test): a colour method's samples keep their
  // depth, so an opaque draw after it (a sky drawn first) replaces it.
  constexpr bool kMayKeepDepth = kColor && !kMayAccum && !kMayMark && M != Method::kSlab;
  [[maybe_unused]] float kept_depth[64];
  [[maybe_unused]] bool keep_depth = false;
  if constexpr (kMayKeepDepth)
    if (__builtin_expect(s_.draw_states && !w.draw->depth_test, 0)) {
      keep_depth = true;
      std::copy(px.depth, px.depth + s_.spp, kept_depth);
    }
  if constexpr (M == Method::kSlab) {  // insert the layer; no per-sample write
    const int at = slab_insert(*px.slab, s_.cfg.slab_layers, w.slab.z, w.slab.mask, rgb16);
    w.slab.kept = at < s_.cfg.slab_layers;
    if (w.slab.kept) {
      c_.samples_written += uint64_t(__builtin_popcountll(w.slab.mask));
      c_.layer_bytes_written += s_.slab_bytes;  // the pixel's layers, rewritten
    }
    w.written = w.depth_written = 0;
    return 1;
  } else if constexpr (selection_of(M) == Method::kLk) {  // lines 10-17: alpha >= reference, in sort order
    const uint64_t a = memo_.fixed_alpha(w.f->alpha);
    // The observer sees each test in its own loop, so the write loop stays
    // the one the golden model runs without it.
    if (obs)
      for (uint32_t j = 0; j < w.m; ++j)
        obs->opacity_tested(w, a, num.alpha_bits, w.lk.ref[j], num.hash_bits,
                            opacity_passes(a, num.alpha_bits, w.lk.ref[j], num.hash_bits));
    for (uint32_t j = 0; j < w.m; ++j) {
      const int i = w.lk.order[j];
      if (opacity_passes(a, num.alpha_bits, w.lk.ref[j], num.hash_bits)) {
        write(i, z[i]);
        wrote |= uint64_t{1} << i;
      }
    }
    c_.samples_opacity_passed += uint64_t(__builtin_popcountll(wrote));
  } else if constexpr (selection_of(M) == Method::kEnderton) {
    for (uint32_t j = 0; j < w.enderton.count; ++j) {
      const int i = w.enderton.list[j];
      write(i, z[i]);
      wrote |= uint64_t{1} << i;
    }
    c_.samples_opacity_passed += w.enderton.chosen;  // the opacity decision: R (original: some then fail depth)
    examined = w.enderton.count;
  } else if constexpr (M == Method::kNaive) {
    const uint64_t a = memo_.fixed_alpha(w.f->alpha);
    if (obs)
      for (uint64_t s = w.survivors; s; s &= s - 1) {
        const int i = __builtin_ctzll(s);
        obs->opacity_tested(w, a, num.alpha_bits, w.naive.ref[i], 32,
                            opacity_passes(a, num.alpha_bits, w.naive.ref[i], 32));
      }
    for (uint64_t s = w.survivors; s; s &= s - 1) {
      const int i = __builtin_ctzll(s);
      if (opacity_passes(a, num.alpha_bits, w.naive.ref[i], 32)) {
        px.write_sample(i, z[i], colour16);
        wrote |= uint64_t{1} << i;
      }
    }
    c_.samples_opacity_passed += uint64_t(__builtin_popcountll(wrote));
  } else {  // a2c, hashed, hashed-a2c (their opacity decision was the mask, before the depth test), opaque
    for (uint64_t s = w.survivors; s; s &= s - 1) {
      const int i = __builtin_ctzll(s);
      px.write_sample(i, z[i], colour16);
    }
    wrote = w.survivors;
    if constexpr (M == Method::kOpaque) c_.samples_opacity_passed += w.m;
  }
  const uint32_t n = uint32_t(__builtin_popcountll(wrote));
  if constexpr (kMayKeepDepth)
    if (keep_depth)
      for (uint64_t s = wrote; s; s &= s - 1) px.depth[__builtin_ctzll(s)] = kept_depth[__builtin_ctzll(s)];
  c_.samples_written += n;
  c_.depth_bytes_written += kDepthSampleBytes * n;
  if constexpr (kMayKeepDepth)
    if (keep_depth) c_.depth_bytes_written -= kDepthSampleBytes * n;
  if constexpr (kMayAccum) {
    if (to_accum)
      c_.target_bytes_written += uint64_t(sample_bytes(fmt.accum)) * n;
    else
      c_.color_bytes_written += uint64_t(s_.bytes.of(Buffer::kColor)) * n;
  } else if constexpr (kColor) {
    c_.color_bytes_written += uint64_t(s_.bytes.of(Buffer::kColor)) * n;
  }
  if constexpr (kMayMark)
    if (mark) c_.target_bytes_written += uint64_t(sample_bytes(fmt.transmittance)) * n;
  w.written = wrote;
  w.depth_written = wrote;
  if constexpr (kMayKeepDepth)
    if (keep_depth) w.depth_written = 0;
  record_plane_keys(w);
  return examined;
}

inline uint32_t WriteStage::run_routed(FragWork& w) {
  const DrawState& d = *w.draw;
  const Fragment& f = *w.f;
  // An opaque draw's fragment is opaque: alpha 1.
  const float src[4] = {f.rgb[0], f.rgb[1], f.rgb[2], w.route == DrawRoute::kOpaque ? 1.0f : f.alpha};
  const bool zw = draw_writes_depth(d), reads = draw_reads_colour(d);
  PixelRef px = w.px;
  uint16_t replace[3];
  if (!reads) {  // every channel replaced: one value for every sample
    replace[0] = replace[1] = replace[2] = 0;
    colour_buffer_blend(d, src, replace);
  }
  for (uint64_t s = w.survivors; s; s &= s - 1) {
    const int i = __builtin_ctzll(s);
    uint16_t* c = px.rgb + 3 * i;
    if (reads) {
      colour_buffer_blend(d, src, c);
    } else {
      c[0] = replace[0];
      c[1] = replace[1];
      c[2] = replace[2];
    }
    if (zw) px.depth[i] = w.z[i];
  }
  const uint32_t n = w.m, nz = zw ? n : 0;
  w.written = w.survivors;
  w.depth_written = zw ? w.survivors : 0;
  record_plane_keys(w);
  c_.samples_written += n;
  c_.depth_bytes_written += kDepthSampleBytes * nz;
  c_.color_bytes_written += uint64_t(s_.bytes.of(Buffer::kColor)) * n;
  if (reads) {  // a read-modify-write of the colour
    c_.samples_blended += n;
    c_.target_bytes_read += uint64_t(s_.bytes.of(Buffer::kColor)) * n;
  }
  return n;
}

inline uint32_t WriteStage::run(FragWork& w) {
  if (w.route != DrawRoute::kMethod) return run_routed(w);
  ROPSIM_DISPATCH(run_as)
}

}  // namespace ropsim
