// An in-order, single-input, single-output pipeline unit: it accepts one
// fragment when its previous initiation interval has passed, and the fragment
// appears at the output after the unit's latency. The subclass supplies the
// function (process) and its timing; this class supplies the protocol and the
// activity accounting. Used by the tracker, the sorter and the alpha-reference
// generator.
#pragma once
#include "rop_context.h"
#include "timed_fifo.h"
#include "unit.h"

namespace ropsim {

using TokenFifo = TimedFifo<FragToken*>;

class PipeUnit : public Unit {
 public:
  PipeUnit(const sc_core::sc_module_name& name, const Clock& clk, RopContext& ctx, TokenFifo& in, TokenFifo& out)
      : Unit(name, clk), ctx_(ctx), in_(in), out_(out) {}

 protected:
  struct Timing {
    uint32_t interval;  ///< cycles before the next fragment may enter (>= 1)
    uint32_t latency;   ///< cycles from entry to the output (>= 1)
  };
  virtual Timing process(FragToken* t, uint64_t now) = 0;

  void step(uint64_t now) override {
    if (now < busy_until_) {
      wake_at(busy_until_);
      return;
    }
    if (!in_.can_pop(now)) {
      if (!in_.empty()) {
        set_activity(Activity::kStarved, now);
        wake_at(in_.head_visible());
      } else if (in_.closed()) {
        if (!out_.closed()) out_.close(now);
        set_activity(Activity::kIdle, now);
      } else {
        set_activity(seen_ ? Activity::kStarved : Activity::kIdle, now);
      }
      return;  // a push or a close wakes the unit
    }
    if (!out_.can_push(now)) {
      set_activity(Activity::kBlocked, now);
      out_.wait_for_space(now);
      return;
    }
    FragToken* t = in_.pop(now);
    seen_ = true;
    ++stats_.fragments;
    const Timing tm = process(t, now);
    out_.push(t, now, now + tm.latency);
    busy_until_ = now + tm.interval;
    set_busy(now, busy_until_, Activity::kStarved);
    if (!in_.empty()) wake_at(std::max(busy_until_, in_.head_visible()));  // else a push wakes it
  }

  RopContext& ctx_;
  TokenFifo& in_;
  TokenFifo& out_;
  uint64_t busy_until_ = 0;
  bool seen_ = false;
};

inline uint32_t ceil_div(uint32_t a, uint32_t b) { return (a + b - 1) / b; }

}  // namespace ropsim
