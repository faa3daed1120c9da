#include "coverage_tracker.h"

namespace ropsim {

PipeUnit::Timing CoverageTracker::process(FragToken* t, uint64_t) {
  t->tr = track_surface(*t->px.tracker, t->survivors, ctx_.golden.numerics.surface_id_bits);
  track_commit(*t->px.tracker, t->survivors);
  new_surfaces_ += t->tr.new_surface;
  ctx_.counters.surface_id_changes += t->tr.new_surface;
  ctx_.counters.tracker_bytes_written += uint64_t(ctx_.tracker_bytes);
  stats_.samples += t->m;
  return {1, cfg_.latency_cycles};
}

}  // namespace ropsim
