#include "coverage_tracker.h"

namespace ropsim {

PipeUnit::Timing CoverageTracker::process(FragToken* t, uint64_t) {
  run_stage(rop_.track(), *t);
  new_surfaces_ += t->lk.track.new_surface;
  stats_.samples += t->m;
  return {1, cfg_.latency_cycles};
}

}  // namespace ropsim
