// What flows through the cycle model: a fragment token (the functional ROP's
// work record plus where the fragment is in the pipeline), the pool that
// recycles tokens, and the retirement that ends a fragment's trip. No unit is
// named here: a retiring fragment releases its pixel through the
// PixelRelease interface, which the pixel ordering unit implements.
#pragma once
#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <vector>

#include "rtl_models/functional/counters.h"
#include "rtl_models/functional/frag_work.h"
#include "rtl_models/observe/attribution.h"
#include "util/errors.h"

namespace ropsim {

/// A fragment in flight: its functional work record, and its place in the pipeline.
struct FragToken : FragWork {
  FragToken() { f = &fragment; }
  FragToken(const FragToken&) = delete;
  FragToken& operator=(const FragToken&) = delete;
  Fragment fragment;       ///< the fragment, as the input delivered it
  uint64_t seq = 0;        ///< position in the input (API order)
  uint32_t rop = 0;        ///< the ROP unit that owns its pixel
  uint64_t pixel_key = 0;  ///< y * width + x
  /// The distributor tile of its pixel, ty * tiles_x + tx (rop_ownership.h),
  /// set by the source when the run attributes per tile (attribution.h).
  uint32_t tile = 0;
  /// Whom its accesses are charged to (attribution.h).
  Owner owner() const { return Owner{fragment.draw_id, tile}; }
  /// With a breakdown (--per-draw, --maps): what the fragment's stages added
  /// to the counters (run_stage), reset when the source issues it.
  bool counting = false;
  Counters counts;
};

/// Runs a stage of the functional ROP on a token; a counting token also
/// collects what the stage added to the counters (the stage's own counters
/// before and after: the units run one at a time, so the difference is this
/// call's).
template <class Stage>
auto run_stage(Stage& stage, FragToken& t) {
  if (!t.counting) return stage.run(t);
  // Charged when the stage has run (after the return value is made).
  struct Charge {
    Stage& stage;
    FragToken& t;
    Counters before;
    ~Charge() {
      Counters d = stage.counters();
      d -= before;
      t.counts += d;
    }
  } charge{stage, t, stage.counters()};
  return stage.run(t);
}

/// Tokens are recycled: their number is bounded by the FIFOs and windows.
/// The pipeline allocates that many up front (reserve), so that the model's
/// memory is what its estimate charged before it was built (memory_estimate.h);
/// a pool that runs dry still allocates another.
class TokenPool {
 public:
  /// Allocates tokens until the pool holds n.
  void reserve(size_t n) {
    all_.reserve(n);
    free_.reserve(n);
    while (all_.size() < n) {
      all_.push_back(std::make_unique<FragToken>());
      free_.push_back(all_.back().get());
    }
  }
  FragToken* get() {
    if (free_.empty()) {
      all_.push_back(std::make_unique<FragToken>());
      return all_.back().get();
    }
    FragToken* t = free_.back();
    free_.pop_back();
    return t;
  }
  void put(FragToken* t) { free_.push_back(t); }
  size_t allocated() const { return all_.size(); }

 private:
  std::vector<std::unique_ptr<FragToken>> all_;
  std::vector<FragToken*> free_;
};

/// Whoever keeps a scoreboard of pixels in flight.
class PixelRelease {
 public:
  /// The fragment of this pixel retires at `cycle`: from the next cycle on
  /// another fragment of the pixel may issue.
  virtual void release(uint64_t pixel_key, uint64_t cycle) = 0;

 protected:
  ~PixelRelease() = default;
};

/// The end of a fragment's trip: its pixel is released in its ROP, its token
/// goes back to the pool.
class Retirement {
 public:
  explicit Retirement(TokenPool& pool) : pool_(pool) {}
  /// The scoreboard of ROP unit `rop`.
  void attach(uint32_t rop, PixelRelease* r) {
    if (scoreboards_.size() <= rop) scoreboards_.resize(rop + 1, nullptr);
    scoreboards_[rop] = r;
  }
  /// The fragment leaves the ROP at `cycle`.
  void retire(FragToken* t, uint64_t cycle) {
    invariant(t->rop < scoreboards_.size() && scoreboards_[t->rop], "a retiring fragment's ROP has a scoreboard");
    scoreboards_[t->rop]->release(t->pixel_key, cycle);
    ++retired_;
    if (cycle > last_) last_ = cycle;
    if (hook) hook(*t, cycle);
    pool_.put(t);
  }
  uint64_t retired() const { return retired_; }
  /// The cycle of the latest retirement.
  uint64_t last_cycle() const { return last_; }
  /// Called for every retiring fragment (tests, tracing).
  std::function<void(const FragToken&, uint64_t cycle)> hook;

 private:
  TokenPool& pool_;
  std::vector<PixelRelease*> scoreboards_;
  uint64_t retired_ = 0, last_ = 0;
};

}  // namespace ropsim
