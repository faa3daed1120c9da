// The depth stage's definitions: each method's depth test, and a draw's own depth state.
// Included by functional_rop_stages.h only, which defines ROPSIM_DISPATCH.
#pragma once

namespace ropsim {

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

}  // namespace ropsim
