#include "rtl_models/units/coverage_tracker.h"

#include "rtl_models/units/unit_timing.h"

namespace ropsim {

PipeUnit::Timing CoverageTracker::process(FragToken* t, uint64_t) {
  if (t->route != DrawRoute::kMethod) return {1, 1};  // an opaque or blended draw's fragment passes through
  run_stage(rop_.track(), *t);
  new_surfaces_ += t->lk.track.new_surface;
  stats_.samples += t->m;
  const UnitTiming tm = tracker_timing(cfg_);
  return {tm.interval, tm.latency};
}

}  // namespace ropsim
