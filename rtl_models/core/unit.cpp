#include "rtl_models/core/unit.h"

#include <stdexcept>

#include "util/errors.h"

namespace ropsim {

const char* to_string(Activity a) {
  switch (a) {
    case Activity::kIdle:
      return "idle";
    case Activity::kBusy:
      return "busy";
    case Activity::kStarved:
      return "input_starved";
    case Activity::kBlocked:
      return "output_blocked";
    case Activity::kHazard:
      return "pixel_hazard";
    case Activity::kMemory:
      return "memory";
  }
  return "?";
}

namespace {
Scheduler& scheduler_of(const Clock& clk) {
  if (!clk.scheduler()) throw InternalError("a Unit needs a Scheduler on its Clock (build the Scheduler first)");
  return *clk.scheduler();
}
}  // namespace

Unit::Unit(const sc_core::sc_module_name& name, const Clock& clk)
    : sc_module(name), clk_(clk), sched_(scheduler_of(clk)), index_(sched_.add(this)) {}

void Unit::charge_tile(bool owned) {
  for (int a = 0; a < kActivities; ++a) {
    const uint64_t n = stats_.cycles[size_t(a)] - charged_[size_t(a)];
    if (owned)
      attr_->unit_cycles(tile_, a, n);
    else
      attr_->unowned_cycles(a, n);
  }
  charged_ = stats_.cycles;
}

void Unit::took_tile(uint32_t tile, uint64_t t) {
  if (has_tile_) {
    if (tile == tile_) return;  // the same tile's cycles keep adding up
    charge_to(t);               // the cycles before t are the previous fragment's tile's
    charge_tile(true);
  }
  // The first fragment's tile also gets the cycles before it (charged at the next switch).
  has_tile_ = true;
  tile_ = tile;
}

void Unit::close_attribution() {
  if (attr_) charge_tile(has_tile_);  // the rest of the run: the last fragment's tile
}

}  // namespace ropsim
