// The functional ROP: the stages of the raster-operations unit as plain C++,
// each holding its per-method behaviour and the counters it owns. The golden
// model calls them in order (FunctionalRop::process); each SystemC unit of
// the cycle model calls one of them and adds its timing. Nothing here knows
// about time, so bit-exactness between the fidelities is structural.
//
//   fetch -> depth test -> [track] -> [sort] -> [reference] -> write
//   fetch -> depth test (not writing) -> blend          (blend passes)
//
// The bracketed stages exist for the methods whose traits ask for them
// (method.h). A method with several passes (passes_of) replays its input once
// per pass; begin_pass selects what the stages do.
#pragma once
#include <array>
#include <cstdint>
#include <string>

#include "rtl_models/algo/conversion_memo.h"
#include "rtl_models/algo/depth.h"
#include "rtl_models/functional/counters.h"
#include "rtl_models/functional/frag_work.h"
#include "rtl_models/functional/method.h"
#include "rtl_models/functional/rop_observer.h"
#include "rtl_models/functional/sample_store.h"
#include "rtl_models/functional/surface_bytes.h"
#include "traces/format/draw_state.h"
#include "traces/format/trace.h"
#include "util/prefetch.h"

namespace ropsim {

/// What every stage derives from the trace header and the method, computed
/// once per run.
struct RopSetup {
  RopSetup(const TraceHeader& h, const MethodConfig& cfg);

  TraceHeader header;
  MethodConfig cfg;
  MethodTraits traits;
  Method selection;  ///< the method whose stochastic pass runs (selection_of)
  PassList passes;   ///< the method's passes
  PassKind pass;     ///< the pass being run (FunctionalRop::begin_pass)
  int spp;
  uint32_t hilbert_n;                            ///< side of the Hilbert curve covering the screen
  uint32_t tracker_bytes;                        ///< lk: ceil((spp + surface_id_bits) / 8), one pixel's tracker state
  std::array<float, 64> offset_x{}, offset_y{};  ///< sample offsets from the pixel centre
  std::array<uint64_t, 65> a2c_prefix{};         ///< a2c: mask of the first k samples
  std::array<uint64_t, 64> slab_bits_of{};       ///< slab: the mask bits sample s owns
  uint32_t slab_bytes = 0;                       ///< slab: one pixel's layers in memory (slab_pixel_bytes)
  RopObserver* observer = nullptr;               ///< told every unit call (FunctionalRop::set_observer)
  /// The trace has draw states: each fragment's draw is looked up (its kind,
  /// route and encoding); without them every fragment takes the method's route.
  bool draw_states = false;
  /// Some draw takes another route than the method's (DrawRoute): opaque,
  /// additive or other blended draws.
  bool routed = false;
  /// The passes begin with the pre-pass of the frame's opaque and blended
  /// draws (a composite method or slab on a routed frame: run_passes); the
  /// method's own passes then skip those draws.
  bool prepass = false;
  TargetEncoding encoding = TargetEncoding::kFloat;  ///< the frame's (frame_encoding)
  /// Each surface's bytes a sample in memory (surface_bytes.h): what the
  /// byte counters, the address map and compression count.
  SurfaceBytes bytes;

  /// The fragment's depth at each sample of mask (docs/numerics.md "Depth"):
  /// from its plane, or its stored per-sample depths.
  void sample_depths(const Fragment& f, uint64_t mask, float* z) const;
  /// The key of the fragment's hash-based random numbers (enderton, naive,
  /// hashed, hashed-a2c).
  uint64_t random_key(const Fragment& f) const;
};

inline void RopSetup::sample_depths(const Fragment& f, uint64_t mask, float* z) const {
  for_each_sample_depth(mask, header.depth_mode == DepthMode::kPlane, f.z0, f.dzdx, f.dzdy, offset_x.data(),
                        offset_y.data(), f.z.data(), [z](int i, float zi) { z[i] = zi; });
}

/// Does some draw of the frame take another route than the method's (an
/// opaque, additive or other blended draw)?
bool has_routed_draws(const TraceHeader& h);

/// The passes a run of method m makes over the trace of header h: the
/// method's (passes_of), after the pre-pass of the opaque and blended draws
/// when the method composites over a background and the frame has such
/// draws (docs/methods.md "Methods on a frame of draw states").
PassList run_passes(const TraceHeader& h, Method m);

/// Does a run of method m on a trace of header h begin with the pre-pass
/// (run_passes)? Its render targets then follow run_uses_transmittance and
/// run_uses_accum (method.h).
bool runs_prepass(const TraceHeader& h, Method m);

/// The per-pixel buffers a run of cfg on a trace of header h keeps beyond
/// depth and colour (the golden model's and the cycle model's store).
StoreTargets store_targets(const TraceHeader& h, const MethodConfig& cfg);

/// A stage's counters; a run's are the sum over the stages.
class Stage {
 public:
  const Counters& counters() const { return c_; }
  /// Adds o's counts to this stage's (FunctionalRop::absorb).
  void absorb(const Stage& o) { c_ += o.c_; }

 protected:
  explicit Stage(const RopSetup& s) : s_(s) {}
  const RopSetup& s_;
  Counters c_;
};

/// Depth test (LK Figure 7 lines 1-3): the samples whose depth is less than or
/// equal to the stored one survive. a2c, hashed and hashed-a2c first keep only
/// the samples their opacity decision chose (the coverage selection).
/// Loads the pixel's tracker state too (lk), so counts its read.
class DepthStage : public Stage {
 public:
  explicit DepthStage(const RopSetup& s) : Stage(s), memo_(s.cfg.numerics.alpha_bits) {}
  /// Fills covered, z, survivors and m; returns the samples tested.
  uint32_t run(FragWork& w);
  template <Method M>
  uint32_t run_as(FragWork& w);  ///< run() for method M, specialised at compile time
  /// hashed, hashed-a2c, slab: the hashes the coverage selection computed (1
  /// and 3 per fragment: chi; xi1, xi2, chi; slab: R + 1 for its R mask bits).
  uint64_t selection_hashes() const { return selection_hashes_; }
  /// Fragments by their draw's kind (DrawKind order); all zero for a trace
  /// without draw states.
  const DrawKindCounts& kind_fragments() const { return kind_fragments_; }
  void absorb(const DepthStage& o) {
    Stage::absorb(o);
    selection_hashes_ += o.selection_hashes_;
    for (int k = 0; k < kDrawKinds; ++k) kind_fragments_[size_t(k)] += o.kind_fragments_[size_t(k)];
  }

 private:
  /// The draw state of f's draw (memoised: a draw's fragments are consecutive),
  /// its kind counted; sets w.draw and w.route.
  const DrawState& look_up_draw(FragWork& w);
  /// The draw's own depth test (framebuffer_blend.h): its function, or every
  /// covered sample when its test is off; each covered sample's depth read.
  uint32_t draw_depth_test(FragWork& w, const DrawState& d);
  ConversionMemo memo_;
  uint64_t selection_hashes_ = 0;
  DrawKindCounts kind_fragments_{};
  uint32_t memo_draw_id_ = UINT32_MAX;
  const DrawState* memo_draw_ = nullptr;
  DrawKind memo_kind_ = DrawKind::kSrcOver;
};

/// Coverage-bitmask surface tracker (lk; Figure 7 lines 4-8 and 18).
class TrackStage : public Stage {
 public:
  explicit TrackStage(const RopSetup& s) : Stage(s) {}
  /// Decides the surface (lk.track) and commits the survivors to the mask.
  void run(FragWork& w);
};

/// Sample ordering (lk; line 9): survivors by the depth already stored.
class SortStage : public Stage {
 public:
  explicit SortStage(const RopSetup& s) : Stage(s) {}
  /// Fills lk.order; returns the samples sorted (m).
  uint32_t run(FragWork& w);
};

/// Reference and selection: lk's alpha references (CalcAlphaRef, lines
/// 10-17), enderton's count and picks, naive's random reference per sample.
class ReferenceStage : public Stage {
 public:
  explicit ReferenceStage(const RopSetup& s) : Stage(s), memo_(s.cfg.numerics.alpha_bits) {}
  /// Fills the method's payload; returns the hashes computed.
  uint32_t run(FragWork& w);
  template <Method M>
  uint32_t run_as(FragWork& w);

 private:
  ConversionMemo memo_;
};

/// Blend (blend passes, method.h PassKind): the surviving samples of the
/// fragment blended into the render targets (blend.h): multiplicative into
/// transmittance, additive into accum; the depth buffer is not written.
class BlendStage : public Stage {
 public:
  explicit BlendStage(const RopSetup& s) : Stage(s) {}
  /// Blends the survivors; returns the samples blended.
  uint32_t run(FragWork& w);
  /// Hints the cache to fetch the pixel's blend targets (no effect on state).
  void prefetch(const FragWork& w) const {
    const uint32_t n = uint32_t(s_.spp);
    if (w.px.trans) prefetch_lines<true>(w.px.trans, n * sample_bytes(s_.cfg.formats.transmittance));
    if (w.px.accum) prefetch_lines<true>(w.px.accum, n * sample_bytes(s_.cfg.formats.accum));
  }
};

/// Opacity test and write: the samples the method keeps get the fragment's
/// depth and colour (RGB binary16).
class WriteStage : public Stage {
 public:
  explicit WriteStage(const RopSetup& s) : Stage(s), memo_(s.cfg.numerics.alpha_bits) {}
  /// Fills written and writes the pixel's state; returns the samples examined.
  uint32_t run(FragWork& w);
  template <Method M>
  uint32_t run_as(FragWork& w);
  /// An opaque or blended draw's fragment (w.route not kMethod): its colour
  /// on each surviving sample (colour_buffer_blend) and, as its depth mask
  /// says, its depth; returns the samples written.
  uint32_t run_routed(FragWork& w);

 private:
  ConversionMemo memo_;
};

class FunctionalRop {
 public:
  /// Throws UserError for bad numerics or a method without a pipeline.
  FunctionalRop(const TraceHeader& h, const MethodConfig& cfg);
  FunctionalRop(const FunctionalRop&) = delete;
  FunctionalRop& operator=(const FunctionalRop&) = delete;

  const RopSetup& setup() const { return setup_; }
  const MethodTraits& traits() const { return setup_.traits; }
  const TraceHeader& header() const { return setup_.header; }

  /// The fragment's pixel state (its tile allocated and cleared on first touch).
  void fetch(FragWork& w) { w.px = store_.pixel(w.f->x, w.f->y); }
  DepthStage& depth() { return depth_; }
  const DepthStage& depth() const { return depth_; }
  TrackStage& track() { return track_; }
  SortStage& sort() { return sort_; }
  ReferenceStage& reference() { return reference_; }
  WriteStage& write() { return write_; }
  BlendStage& blend() { return blend_; }

  /// The method's passes over the input (1 for most methods).
  int passes() const { return setup_.passes.count; }
  /// Selects pass i (0-based) for the fragments that follow; every pass
  /// replays the whole input. The state carries over from pass to pass.
  /// i out of [0, passes()) is a broken invariant (InternalError).
  void begin_pass(int i);
  PassKind pass() const { return setup_.pass; }
  /// Does the current pass read and write the lk tracker?
  bool pass_uses_tracker() const { return setup_.traits.tracker && setup_.pass == PassKind::kStochastic; }
  /// The method's image from the final state: the box-filter resolve, or its
  /// composite (alpha correction, depth-based, wboit: composite.h).
  Image resolve() const;

  /// Tells o (not owned; null: nobody) every call the stages make of a unit's
  /// rule, with its inputs and outputs (rop_observer.h), from here on.
  void set_observer(RopObserver* o) { setup_.observer = o; }

  /// One fragment through every stage of its method, in order: fetch, the
  /// depth test, and unless it killed the fragment, the stages its traits name.
  void process(FragWork& w) { (this->*process_)(w); }

  /// Takes over o's state and counts: o, a ROP of the same trace, method and
  /// pass, has processed the fragments of tiles this one never touched (the
  /// golden model's threads, one ROP each over its own tiles). Every rule is
  /// per pixel, so the union is the state one ROP would hold after all the
  /// fragments, and the counts add. o is left without tiles. Throws
  /// InternalError if the two ROPs differ or share a tile.
  void absorb(FunctionalRop& o);

  /// The stages' counters summed, with the tiles allocated so far.
  Counters counters() const;
  SampleStore& store() { return store_; }
  const SampleStore& store() const { return store_; }

 private:
  RopSetup setup_;
  SampleStore store_;
  DepthStage depth_;
  TrackStage track_;
  SortStage sort_;
  ReferenceStage reference_;
  WriteStage write_;
  BlendStage blend_;
  template <Method M>
  void process_as(FragWork& w);
  void (FunctionalRop::*process_)(FragWork&);  ///< process_as<the run's method>
};

}  // namespace ropsim

#include "rtl_models/functional/functional_rop_stages.h"  // IWYU pragma: export
