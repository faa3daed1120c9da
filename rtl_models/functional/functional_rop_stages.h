// The stages' definitions, inline so that the golden model's specialised
// process_as<M> and each SystemC unit's stage call compile to straight code
// (included by functional_rop.h only).
#pragma once
#include "rtl_models/algo/alpha_ref.h"
#include "rtl_models/algo/blend.h"
#include "rtl_models/algo/compression.h"
#include "rtl_models/algo/depth.h"
#include "rtl_models/algo/hilbert.h"
#include "rtl_models/algo/method_kernels.h"
#include "rtl_models/algo/opacity.h"
#include "rtl_models/algo/random_hash.h"
#include "rtl_models/algo/slab.h"
#include "rtl_models/algo/sort_order.h"
#include "rtl_models/functional/framebuffer_blend.h"

namespace ropsim {

inline uint64_t RopSetup::random_key(const Fragment& f) const {
  return fragment_key(cfg.seed, f.draw_id, f.prim_id, f.x, f.y);
}

// ------------------------------------------------------------------ stages
//
// Each stage's behaviour is written once, per method with `if constexpr`; the
// golden model runs the specialisation of its method (process_as<M>, every
// stage inlined), the units run the same code through run()'s dispatch.

#define ROPSIM_DISPATCH(call)                   \
  switch (s_.cfg.method) {                      \
    case Method::kLk:                           \
      return call<Method::kLk>(w);              \
    case Method::kEnderton:                     \
      return call<Method::kEnderton>(w);        \
    case Method::kNaive:                        \
      return call<Method::kNaive>(w);           \
    case Method::kA2c:                          \
      return call<Method::kA2c>(w);             \
    case Method::kOpaque:                       \
      return call<Method::kOpaque>(w);          \
    case Method::kHashed:                       \
      return call<Method::kHashed>(w);          \
    case Method::kHashedA2c:                    \
      return call<Method::kHashedA2c>(w);       \
    case Method::kSlab:                         \
      return call<Method::kSlab>(w);            \
    case Method::kWboit:                        \
      return call<Method::kWboit>(w);           \
    case Method::kLkAc:                         \
      return call<Method::kLkAc>(w);            \
    case Method::kLkDepth:                      \
      return call<Method::kLkDepth>(w);         \
    case Method::kLkDepthAc:                    \
      return call<Method::kLkDepthAc>(w);       \
    case Method::kEndertonAc:                   \
      return call<Method::kEndertonAc>(w);      \
    case Method::kEndertonDepth:                \
      return call<Method::kEndertonDepth>(w);   \
    case Method::kEndertonDepthAc:              \
      return call<Method::kEndertonDepthAc>(w); \
    case Method::kBlend:                        \
      return call<Method::kBlend>(w);           \
    case Method::kReference:                    \
      break;                                    \
  }                                             \
  return 0;

inline const DrawState& DepthStage::look_up_draw(FragWork& w) {
  const uint32_t id = w.f->draw_id;
  if (id != memo_draw_id_ || !memo_draw_) {
    memo_draw_ = &s_.header.draws.at(id);
    memo_draw_id_ = id;
    memo_kind_ = draw_kind(*memo_draw_);
  }
  if (s_.pass == s_.passes.pass[0]) ++kind_fragments_[size_t(memo_kind_)];  // once per run, not per pass
  w.draw = memo_draw_;
  w.route = route_of(memo_kind_);
  return *memo_draw_;
}

inline uint32_t DepthStage::draw_depth_test(FragWork& w, const DrawState& d) {
  const Fragment& f = *w.f;
  const uint32_t covered = uint32_t(__builtin_popcountll(f.coverage));
  c_.depth_bytes_read += kDepthSampleBytes * covered;
  uint64_t S = 0;
  const float* stored = w.px.depth;
  float* z = w.z;
  for_each_sample_depth(f.coverage, s_.header.depth_mode == DepthMode::kPlane, f.z0, f.dzdx, f.dzdy, s_.offset_x.data(),
                        s_.offset_y.data(), f.z.data(), [&](int i, float zi) {
                          z[i] = zi;
                          S |= uint64_t{!d.depth_test || depth_func_passes(d.depth_func, zi, stored[i])} << i;
                        });
  w.covered = f.coverage;
  w.survivors = S;
  w.m = uint32_t(__builtin_popcountll(S));
  c_.samples_depth_passed += w.m;
  if (s_.observer) s_.observer->depth_tested(w);
  return covered;
}

template <Method M>
inline uint32_t DepthStage::run_as(FragWork& w) {
  constexpr MethodTraits kT = traits(selection_of(M));
  const Fragment& f = *w.f;
  const uint32_t covered = uint32_t(__builtin_popcountll(f.coverage));
  ++c_.fragments;
  uint64_t tested = f.coverage;
  // Blend passes: the plain test, no coverage selection, no tracker.
  [[maybe_unused]] const bool stochastic = !has_blend_pass(M) || !is_blend_pass(s_.pass);
  if constexpr (M == Method::kBlend) {
    // Every fragment: its draw's own test and blend (framebuffer_blend.h);
    // one route, the framebuffer's.
    c_.samples_tested += covered;
    const DrawState& d = look_up_draw(w);
    w.route = DrawRoute::kMethod;
    return draw_depth_test(w, d);
  }
  w.route = DrawRoute::kMethod;
  if (s_.draw_states) {
    // A frame of draw states: opaque and blended draws take their own depth
    // test and leave the method's stages (docs/methods.md). With a pre-pass,
    // they are its only fragments, and the method's passes skip them.
    look_up_draw(w);
    if (s_.prepass && (w.route != DrawRoute::kMethod) != (s_.pass == PassKind::kPrepass)) {
      w.covered = w.survivors = 0;  // not this pass's: it tests and reads nothing
      w.m = 0;
      return 0;
    }
  }
  c_.samples_tested += covered;
  if (w.route != DrawRoute::kMethod) return draw_depth_test(w, *w.draw);
  if constexpr (kT.coverage_select) {
    // The opacity decision as a sample mask, made before the depth test.
    const uint64_t a = memo_.fixed_alpha(f.alpha);
    const int alpha_bits = s_.cfg.numerics.alpha_bits;
    if constexpr (M == Method::kA2c) {
      // a2c: k = floor(alpha spp + dither) samples of a fixed order.
      tested &= s_.a2c_prefix[a2c_sample_count(a, alpha_bits, s_.spp, f.x, f.y)];
    } else if constexpr (M == Method::kHashed) {
      // hashed: all covered samples or none, against one hashed threshold.
      if (!hashed_alpha_passes(a, alpha_bits, s_.random_key(f))) tested = 0;
      selection_hashes_ += 1;
    } else if constexpr (M == Method::kHashedA2c) {
      // hashed-a2c: one threshold per 1/spp stratum, in a hashed order (Eq. 9).
      tested &= hashed_a2c_mask(a, alpha_bits, uint32_t(s_.spp), s_.random_key(f));
      selection_hashes_ += 3;
    }
    c_.samples_opacity_passed += uint64_t(__builtin_popcountll(tested));
    if (!tested) {  // discarded: the fragment reaches no depth test and reads no depth
      w.covered = w.survivors = 0;
      w.m = 0;
      return 0;
    }
  }
  if constexpr (kT.tracker)
    if (stochastic) c_.tracker_bytes_read += s_.tracker_bytes;
  if constexpr (M == Method::kSlab) {
    // SLAB has no per-sample depth: it reads the pixel's layers, draws the
    // fragment's stratified b-bit mask among the bits of its covered samples
    // and lets it on only where nearer layers leave some of its bits open.
    c_.layer_bytes_read += s_.slab_bytes;
    float z[64];
    s_.sample_depths(f, f.coverage, z);
    if (s_.prepass && w.draw->depth_test) {
      // Over a pre-pass's background: only the samples in front of its
      // depth (LESS_EQUAL), each covered sample's depth read.
      c_.depth_bytes_read += kDepthSampleBytes * covered;
      for (uint64_t m = f.coverage; m; m &= m - 1) {
        const int i = __builtin_ctzll(m);
        if (!depth_passes(z[i], w.px.depth[i])) tested &= ~(uint64_t{1} << i);
      }
    }
    float zf = 0;
    uint64_t candidates = 0;
    bool first = true;
    for (uint64_t m = tested; m; m &= m - 1) {
      const int i = __builtin_ctzll(m);
      zf = first || z[i] < zf ? z[i] : zf;
      first = false;
      candidates |= s_.slab_bits_of[size_t(i)];
    }
    uint32_t hashes = 0;
    const uint64_t mask = candidates ? slab_mask(memo_.fixed_alpha(f.alpha), s_.cfg.numerics.alpha_bits, candidates,
                                                 s_.random_key(f), &hashes)
                                     : 0;
    selection_hashes_ += hashes;
    c_.samples_opacity_passed += uint64_t(__builtin_popcountll(mask));
    const bool open = mask != 0 && !slab_occluded(*w.px.slab, zf, mask);
    w.slab.z = zf;
    w.slab.mask = mask;
    w.covered = f.coverage;  // every covered sample is examined
    w.survivors = open ? tested : 0;
    w.m = open ? uint32_t(__builtin_popcountll(tested)) : 0;
    c_.samples_depth_passed += w.m;
    return covered;
  }
  // The stored depth of each tested sample is read (a2c, hashed, hashed-a2c:
  // only the samples their mask kept).
  const uint32_t n_tested = uint32_t(__builtin_popcountll(tested));
  c_.depth_bytes_read += kDepthSampleBytes * n_tested;
  // Each tested sample's depth and its test, in one pass; branch-free:
  // pass/fail is data-dependent.
  uint64_t S = 0;
  float* z = w.z;
  const float* stored = w.px.depth;
  const bool plane = s_.header.depth_mode == DepthMode::kPlane;
#if defined(__SSE2__)
  // Four or more samples: every sample's depth and test four at a time
  // (identical values; the untested samples' results are masked off).
  if (s_.spp >= 4) {
    S = tested & sample_depths_and_test(s_.spp, plane, f.z0, f.dzdx, f.dzdy, s_.offset_x.data(), s_.offset_y.data(),
                                        f.z.data(), stored, z);
  } else
#endif
  {
    for_each_sample_depth(tested, plane, f.z0, f.dzdx, f.dzdy, s_.offset_x.data(), s_.offset_y.data(), f.z.data(),
                          [&](int i, float zi) {
                            z[i] = zi;
                            S |= uint64_t{depth_passes(zi, stored[i])} << i;
                          });
  }
  // A src-over draw with its depth test off (a HUD, a UI): every tested
  // sample survives; the method's write still stores its depth.
  if (s_.draw_states && !w.draw->depth_test) S = tested;
  w.covered = tested;
  w.survivors = S;
  w.m = uint32_t(__builtin_popcountll(S));
  c_.samples_depth_passed += w.m;
  if (s_.observer) s_.observer->depth_tested(w);
  return n_tested;
}

inline uint32_t DepthStage::run(FragWork& w) { ROPSIM_DISPATCH(run_as) }

inline void TrackStage::run(FragWork& w) {
  if (w.route != DrawRoute::kMethod) return;  // opaque and blended draws bypass the tracker
  RopObserver* const obs = s_.observer;
  TrackerState before{};
  if (obs) before = *w.px.tracker;
  w.lk.track = track_surface(*w.px.tracker, w.survivors, s_.cfg.numerics.surface_id_bits);
  track_commit(*w.px.tracker, w.survivors);  // line 18: the state is not read again for this fragment
  if (obs) obs->tracked(w, before, s_.cfg.numerics.surface_id_bits);
  c_.surface_id_changes += w.lk.track.new_surface;
  c_.tracker_bytes_written += s_.tracker_bytes;
}

inline uint32_t SortStage::run(FragWork& w) {
  if (w.route != DrawRoute::kMethod) return 0;  // opaque and blended draws bypass the sorter
  const int m = sort_by_stored_depth(w.px.depth, w.survivors, w.lk.order);
  c_.sorts += m > 1;
  if (s_.observer) s_.observer->sorted(w);
  return uint32_t(m);
}

template <Method M>
inline uint32_t ReferenceStage::run_as(FragWork& w) {
  const Fragment& f = *w.f;
  if constexpr (selection_of(M) == Method::kLk) {
    const uint64_t pixel_id = hilbert_xy2d(s_.hilbert_n, f.x, f.y);
    calc_alpha_refs(w.lk.track.n, int(w.m), pixel_id, w.lk.track.surface_id, uint32_t(s_.spp),
                    s_.cfg.numerics.hash_bits, w.lk.ref);
    if (s_.observer) s_.observer->referenced(w, s_.hilbert_n, pixel_id, s_.cfg.numerics.hash_bits);
    return w.m;
  } else if constexpr (selection_of(M) == Method::kEnderton) {
    // Depth-first: R of the m depth survivors. Original: R of the c covered
    // samples, then only the chosen that passed the depth test are written.
    const bool original = s_.cfg.enderton_selection == EndertonSelection::kOriginal;
    const uint64_t pool = original ? w.covered : w.survivors;
    const uint32_t n = uint32_t(__builtin_popcountll(pool));
    int k = 0;
    for (uint64_t s = pool; s; s &= s - 1) w.enderton.list[k++] = __builtin_ctzll(s);
    const uint64_t key = s_.random_key(f);
    const uint32_t r = enderton_count(memo_.fixed_alpha(f.alpha), s_.cfg.numerics.alpha_bits, n, key);
    enderton_pick(w.enderton.list, n, r, key);
    w.enderton.chosen = w.enderton.count = r;
    if (original) {  // keep the chosen survivors, in choice order
      uint32_t kept = 0;
      for (uint32_t j = 0; j < r; ++j)
        if (w.survivors >> w.enderton.list[j] & 1) w.enderton.list[kept++] = w.enderton.list[j];
      w.enderton.count = kept;
    }
    return r + 1;  // the count's hash and one per pick
  } else if constexpr (M == Method::kNaive) {
    const uint64_t key = s_.random_key(f);
    for (uint64_t s = w.survivors; s; s &= s - 1) {
      const int i = __builtin_ctzll(s);
      w.naive.ref[i] = fragment_random(key, uint32_t(i) + 1);
    }
    return w.m;
  } else {
    return 0;  // no reference stage
  }
}

inline uint32_t ReferenceStage::run(FragWork& w) {
  if (w.route != DrawRoute::kMethod) return 0;  // opaque and blended draws need no reference
  ROPSIM_DISPATCH(run_as)
}

/// The depths a stage wrote (w.depth_written) now lie on the fragment's
/// primitive's plane: their plane keys become its (the rasterizer-plane
/// depth encoder, compression.h). Every stage that writes depth calls it
/// last.
inline void record_plane_keys(const FragWork& w) {
  if (!w.px.plane) return;
  const uint64_t k = plane_key(w.f->draw_id, w.f->prim_id);
  for (uint64_t s = w.depth_written; s; s &= s - 1) w.px.plane[__builtin_ctzll(s)] = k;
}

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

#undef ROPSIM_DISPATCH

}  // namespace ropsim
