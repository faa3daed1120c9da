#include "unit.h"

namespace ropsim {

const char* to_string(Activity a) {
  switch (a) {
    case Activity::kIdle: return "idle";
    case Activity::kBusy: return "busy";
    case Activity::kStarved: return "input_starved";
    case Activity::kBlocked: return "output_blocked";
    case Activity::kHazard: return "pixel_hazard";
    case Activity::kMemory: return "memory";
  }
  return "?";
}

Unit::Unit(const sc_core::sc_module_name& name, const Clock& clk) : sc_module(name), clk_(clk) {
  SC_METHOD(run);
  sensitive << wake_;
  dont_initialize();
}

void Unit::run() {
  ++stats_.activations;
  const uint64_t now = clk_.now();
  clk_.set_current(now);
  armed_ = ~uint64_t{0};
  size_t due = 0;
  while (due < wakes_.size() && wakes_[due] <= now) ++due;
  wakes_.erase(wakes_.begin(), wakes_.begin() + ptrdiff_t(due));
  step(now);
  if (!wakes_.empty() && wakes_.front() < armed_) notify(wakes_.front());
}

}  // namespace ropsim
