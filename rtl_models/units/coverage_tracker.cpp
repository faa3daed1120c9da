#include "coverage_tracker.h"

#include "unit_timing.h"

namespace ropsim {

PipeUnit::Timing CoverageTracker::process(FragToken* t, uint64_t) {
  run_stage(rop_.track(), *t);
  new_surfaces_ += t->lk.track.new_surface;
  stats_.samples += t->m;
  const UnitTiming tm = tracker_timing(cfg_);
  return {tm.interval, tm.latency};
}

}  // namespace ropsim
