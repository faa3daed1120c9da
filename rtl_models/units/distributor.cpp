#include "rtl_models/units/distributor.h"

namespace ropsim {

Distributor::Distributor(const sc_core::sc_module_name& name, const Clock& clk, const HwConfig::Distributor& cfg,
                         uint32_t screen_width, TokenFifo& in, std::vector<TokenFifo*> outs)
    : DecoupledUnit(name, clk), cfg_(cfg), owner_(cfg, screen_width), in_(in), outs_(std::move(outs)) {}

void Distributor::advance(uint64_t limit) {
  while (!closed_) {
    const uint64_t t = t_;
    if (t > limit) return wake_at(t);
    // Decoupled, a clock routes several fragments: all that are visible at it
    // must be in (in lockstep they are, by SystemC time).
    if (limit == kForever && t > in_.settled()) return;  // settle() comes back here
    TokenFifo* blocked = nullptr;
    while (n_ < cfg_.fragments_per_clock && in_.can_pop(t)) {
      FragToken* tok = in_.front();
      const uint32_t r = rop_of(tok->f->x, tok->f->y);
      TokenFifo& o = *outs_[r];
      if (!o.can_push(t)) {
        // Decoupled: a slot the ROP has not yet freed may still free before t.
        if (limit == kForever && o.space_from() == TokenFifo::kUndecided) return o.notify_on_pop();
        blocked = &o;
        break;
      }
      in_.pop(t);
      took(tok->tile, t);
      tok->rop = r;
      o.push(tok, t, t + cfg_.latency_cycles);
      ++n_;
      ++stats_.fragments;
    }
    // Clock t is decided.
    if (n_) {
      seen_ = true;
      set_activity(Activity::kBusy, t);
      n_ = 0;
      t_ = t + 1;
      continue;
    }
    if (blocked) {  // the head's ROP FIFO is full
      set_activity(Activity::kBlocked, t);
      const uint64_t s = blocked->space_from();
      if (s == TokenFifo::kUndecided) return blocked->wait_for_space(t);
      t_ = s;
      continue;
    }
    // Nothing visible at t: starved (idle before the first fragment) until
    // the head is visible, a push arrives, or the input closes.
    set_activity(seen_ ? Activity::kStarved : Activity::kIdle, t);
    if (!in_.empty()) {
      t_ = in_.head_visible();
      continue;
    }
    if (!in_.closed()) return;  // a push or a close comes back here
    const uint64_t c = std::max(t, close_seen_);
    if (c > limit) return wake_at(c);
    closed_ = true;
    for (auto* o : outs_) o->close(c);
    set_activity(Activity::kIdle, c);
  }
}

}  // namespace ropsim
