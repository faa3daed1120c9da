#include "rtl_models/units/alpha_ref_gen.h"

#include "rtl_models/units/unit_timing.h"

namespace ropsim {

PipeUnit::Timing AlphaRefGen::process(FragToken* t, uint64_t) {
  if (t->route != DrawRoute::kMethod) return {1, 1};  // an opaque or blended draw's fragment passes through
  const uint32_t hashes = run_stage(rop_.reference(), *t);
  stats_.samples += hashes;
  const UnitTiming tm = alpha_ref_timing(cfg_, hashes);
  return {tm.interval, tm.latency};
}

}  // namespace ropsim
