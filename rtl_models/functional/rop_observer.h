// An observer of the functional ROP's unit calls: after a stage applies one
// of the bit-level rules of rtl_models/algo/ (the functions the random
// vectors of `ropsim vectors` exercise), it tells the observer the rule's
// inputs and outputs exactly as it used them. `ropsim vectors UNIT --trace`
// writes them as vectors from real content (sim/driver/vectors.h). One hook
// for both fidelities (FunctionalRop::set_observer; the SystemC units run
// the same stages); with none set, each stage pays one test of a pointer.
#pragma once
#include <cstdint>

#include "rtl_models/algo/tracker.h"
#include "rtl_models/functional/frag_work.h"

namespace ropsim {

class RopObserver {
 public:
  virtual ~RopObserver() = default;
  /// The depth test of the fragment (for_each_sample_depth and depth_passes,
  /// every method but slab, every pass): w.covered the samples tested, w.z
  /// their depths, w.px.depth the stored depths (the test writes none),
  /// w.survivors the samples that passed. Not called for a fragment whose
  /// coverage selection kept no sample: it reaches no depth test.
  virtual void depth_tested(const FragWork& w) { (void)w; }
  /// The surface tracker (track_surface, then track_commit): before the
  /// pixel's state the fragment found, w.survivors the samples it got, w.lk.track
  /// the decision, *w.px.tracker the state after the commit.
  virtual void tracked(const FragWork& w, const TrackerState& before, int surface_id_bits) {
    (void)w, (void)before, (void)surface_id_bits;
  }
  /// The sorter (sort_by_stored_depth): w.survivors ordered by the stored
  /// depths w.px.depth (not yet written) into w.lk.order[0..w.m).
  virtual void sorted(const FragWork& w) { (void)w; }
  /// The alpha-reference generator (hilbert_xy2d, then calc_alpha_refs): the
  /// pixel's Hilbert index pixel_id on the hilbert_n-square grid, and
  /// w.lk.ref[j] the reference of sequence index w.lk.track.n + j for
  /// surface w.lk.track.surface_id, j < w.m.
  virtual void referenced(const FragWork& w, uint32_t hilbert_n, uint64_t pixel_id, int hash_bits) {
    (void)w, (void)hilbert_n, (void)pixel_id, (void)hash_bits;
  }
  /// One opacity test (opacity_passes; lk, naive): the fragment's opacity
  /// a_fixed against ref, and whether it passed.
  virtual void opacity_tested(const FragWork& w, uint64_t a_fixed, int alpha_bits, uint32_t ref, int hash_bits,
                              bool passed) {
    (void)w, (void)a_fixed, (void)alpha_bits, (void)ref, (void)hash_bits, (void)passed;
  }
};

}  // namespace ropsim
