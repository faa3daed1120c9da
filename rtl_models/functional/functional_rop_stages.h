// The stages' definitions, inline so that the golden model's specialised
// process_as<M> and each SystemC unit's stage call compile to straight code
// (included by functional_rop.h only). The depth, write and blend stages
// have a header each; the tracker, sorter and reference stages are here.
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

/// The depths a stage wrote (w.depth_written) now lie on the fragment's
/// primitive's plane: their plane keys become its (the rasterizer-plane
/// depth encoder, compression.h). Every stage that writes depth calls it
/// last.
inline void record_plane_keys(const FragWork& w) {
  if (!w.px.plane) return;
  const uint64_t k = plane_key(w.f->draw_id, w.f->prim_id);
  for (uint64_t s = w.depth_written; s; s &= s - 1) w.px.plane[__builtin_ctzll(s)] = k;
}

}  // namespace ropsim

#include "rtl_models/functional/functional_stage_blend.h"
#include "rtl_models/functional/functional_stage_depth.h"
#include "rtl_models/functional/functional_stage_write.h"

namespace ropsim {

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

}  // namespace ropsim

#undef ROPSIM_DISPATCH
