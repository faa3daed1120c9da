#include "rtl_models/units/pixel_ordering.h"

namespace ropsim {

PixelOrdering::PixelOrdering(const sc_core::sc_module_name& name, const Clock& clk, const HwConfig::Ordering& cfg,
                             TokenFifo& in, TokenFifo& out)
    : Unit(name, clk), cfg_(cfg), in_(in), out_(out), in_flight_(cfg.pixels_in_flight) {
  window_.reserve(cfg.window);
}

void PixelOrdering::release(uint64_t pixel_key, uint64_t cycle) {
  // Usually the latest (writebacks retire in order); a depth-test kill may
  // come before writebacks already announced.
  releases_.push({cycle, pixel_key});
  if (waiting_release_) wake_at(cycle + 1);
}

void PixelOrdering::step(uint64_t now) {
  waiting_release_ = false;
  // Retirements before now. A pixel retired at cycle c may issue again from
  // c + 1 (as a FIFO slot freed at c is reused from c + 1), so a depth-test
  // kill and this unit in the same cycle never depend on SystemC's run order.
  while (!releases_.empty() && releases_.front().first < now) {
    in_flight_.erase(releases_.front().second);
    releases_.pop_front();
  }
  while (window_.size() < cfg_.window && in_.can_pop(now)) {
    window_.push_back(in_.pop(now));
    took(window_.back()->tile, now);
  }
  if (now < busy_until_) {
    wake_at(busy_until_);
    return;
  }
  // The oldest fragment whose pixel is neither in flight nor held by an older
  // waiting fragment.
  int pick = -1;
  if (in_flight_.size() < cfg_.pixels_in_flight) {
    for (size_t i = 0; i < window_.size() && pick < 0; ++i) {
      const uint64_t key = window_[i]->pixel_key;
      if (in_flight_.contains(key)) continue;
      bool shadowed = false;
      for (size_t j = 0; j < i && !shadowed; ++j) shadowed = window_[j]->pixel_key == key;
      if (!shadowed) pick = int(i);
    }
  }
  if (pick >= 0 && out_.can_push(now)) {
    FragToken* t = window_[size_t(pick)];
    window_.erase(window_.begin() + pick);
    overtakes_ += pick > 0;
    in_flight_.insert(t->pixel_key);
    if (in_flight_.size() > max_in_flight_) max_in_flight_ = in_flight_.size();
    out_.push(t, now, now + cfg_.latency_cycles);
    seen_ = true;
    ++stats_.fragments;
    busy_until_ = now + 1;
    set_busy(now, busy_until_, Activity::kStarved);
    // The next clock matters only if there is something to issue or to close
    // (a push, a close or a release wakes the unit otherwise).
    if (!window_.empty() || !in_.empty() || in_.closed()) wake_at(now + 1);
    return;
  }
  if (pick >= 0) {
    set_activity(Activity::kBlocked, now);
    out_.wait_for_space(now);
  } else if (!window_.empty()) {
    set_activity(Activity::kHazard, now);
    waiting_release_ = true;
    if (!releases_.empty()) wake_at(releases_.front().first + 1);
  } else if (in_.occupied(now)) {
    set_activity(Activity::kStarved, now);
  } else if (in_.closed_by(now)) {
    if (!out_.closed()) out_.close(now);
    set_activity(Activity::kIdle, now);
    return;
  } else {
    set_activity(seen_ ? Activity::kStarved : Activity::kIdle, now);
  }
  // More input for the window: wake when it becomes visible (a push wakes us
  // otherwise).
  if (window_.size() < cfg_.window && !in_.empty()) wake_at(std::max(now + 1, in_.head_visible()));
}

std::vector<Unit::Extra> PixelOrdering::extras() const {
  return {{"overtakes", double(overtakes_), "fragments", "fragments issued ahead of an older waiting fragment"},
          {"max_pixels_in_flight", double(max_in_flight_), "pixels", "most pixels in flight at once (scoreboard)"}};
}

}  // namespace ropsim
