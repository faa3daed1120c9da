#include "distributor.h"

namespace ropsim {

Distributor::Distributor(const sc_core::sc_module_name& name, const Clock& clk, const HwConfig::Distributor& cfg,
                         uint32_t screen_width, TokenFifo& in, std::vector<TokenFifo*> outs)
    : Unit(name, clk), cfg_(cfg), in_(in), outs_(std::move(outs)) {
  while ((1u << tile_shift_) < cfg.tile_pixels) ++tile_shift_;
  tiles_x_ = (screen_width + cfg.tile_pixels - 1) / cfg.tile_pixels;
}

void Distributor::step(uint64_t now) {
  if (now < busy_until_) {
    wake_at(busy_until_);
    return;
  }
  uint32_t n = 0;
  bool blocked = false;
  while (n < cfg_.fragments_per_clock && in_.can_pop(now)) {
    FragToken* t = in_.front();
    const uint32_t r = rop_of(t->f.x, t->f.y);
    if (!outs_[r]->can_push(now)) {
      blocked = true;
      outs_[r]->wait_for_space(now);
      break;
    }
    in_.pop(now);
    t->rop = r;
    outs_[r]->push(t, now, now + cfg_.latency_cycles);
    ++n;
  }
  stats_.fragments += n;
  if (n) {
    seen_ = true;
    busy_until_ = now + 1;
    set_activity(Activity::kBusy, now);
    wake_at(now + 1);
  } else if (blocked) {
    set_activity(Activity::kBlocked, now);
  } else if (!in_.empty()) {
    set_activity(Activity::kStarved, now);
    wake_at(in_.head_visible());
  } else if (in_.closed()) {
    if (!closed_) {
      closed_ = true;
      for (auto* o : outs_) o->close(now);
    }
    set_activity(Activity::kIdle, now);
  } else {
    set_activity(seen_ ? Activity::kStarved : Activity::kIdle, now);
  }
}

}  // namespace ropsim
