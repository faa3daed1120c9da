// An in-order, single-input, single-output pipeline unit: it accepts one
// fragment when its previous initiation interval has passed, and the fragment
// appears at the output after the unit's latency. The subclass supplies the
// function (process) and its timing; this class supplies the protocol and the
// activity accounting. Used by the sorter and the alpha-reference generator
// and the tracker, whose functions use no timed shared state, so they may run
// decoupled (unit.h).
#pragma once
#include "rtl_models/algo/bits.h"
#include "rtl_models/core/timed_fifo.h"
#include "rtl_models/core/token.h"
#include "rtl_models/core/unit.h"
#include "rtl_models/functional/functional_rop.h"

namespace ropsim {

using TokenFifo = TimedFifo<FragToken*>;

class PipeUnit : public DecoupledUnit {
 public:
  PipeUnit(const sc_core::sc_module_name& name, const Clock& clk, FunctionalRop& rop, TokenFifo& in, TokenFifo& out)
      : DecoupledUnit(name, clk), rop_(rop), in_(in), out_(out) {}

 protected:
  struct Timing {
    uint32_t interval;  ///< cycles before the next fragment may enter (>= 1)
    uint32_t latency;   ///< cycles from entry to the output (>= 1)
  };
  /// The unit's function on one fragment entering at cycle t.
  virtual Timing process(FragToken* tok, uint64_t t) = 0;

  void advance(uint64_t limit) override {
    for (;;) {
      if (in_.empty()) {
        // Everything is through; after the input closes, so does the output.
        if (in_.closed() && !out_.closed()) {
          const uint64_t t = std::max(close_seen_, busy_until_);
          if (t > limit) return wake_at(t);
          out_.close(t);
          set_activity(Activity::kIdle, t);
        }
        return;  // a push or a close comes back here
      }
      // The head enters when it is visible, the interval has passed and the
      // output has a slot (kBlocked until then; kStarved follows a busy spell).
      uint64_t t = std::max(busy_until_, in_.head_visible());
      if (t > limit) return wake_at(t);
      if (!out_.can_push(t)) {
        set_activity(Activity::kBlocked, t);
        const uint64_t s = out_.space_from();
        if (s == TokenFifo::kUndecided) return out_.wait_for_space(t);
        t = s;  // the slot's cycle (> t): blocked until then
        if (t > limit) return wake_at(t);
      }
      FragToken* tok = in_.pop(t);
      took(tok->tile, t);
      ++stats_.fragments;
      const Timing tm = process(tok, t);
      out_.push(tok, t, t + tm.latency);
      busy_until_ = t + tm.interval;
      set_busy(t, busy_until_, Activity::kStarved);
    }
  }

  FunctionalRop& rop_;  ///< the stage this unit runs
  TokenFifo& in_;
  TokenFifo& out_;
  uint64_t busy_until_ = 0;
};

}  // namespace ropsim
