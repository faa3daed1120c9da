#include "unit.h"

#include <stdexcept>

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
  if (!clk.scheduler()) throw std::logic_error("a Unit needs a Scheduler on its Clock (build the Scheduler first)");
  return *clk.scheduler();
}
}  // namespace

Unit::Unit(const sc_core::sc_module_name& name, const Clock& clk)
    : sc_module(name), clk_(clk), sched_(scheduler_of(clk)), index_(sched_.add(this)) {}

}  // namespace ropsim
