#include "rtl_models/units/sample_sorter.h"

namespace ropsim {

PipeUnit::Timing SampleSorter::process(FragToken* t, uint64_t) {
  if (t->route != DrawRoute::kMethod) return {1, 1};  // an opaque or blended draw's fragment passes through
  // The order is the sort stage's (sort_order.h), which every variant's
  // network produces (SortVariants tests); the variant supplies the timing.
  const uint32_t m = run_stage(rop_.sort(), *t);
  stats_.samples += m;
  return {algo_->interval_cycles(int(m)), algo_->latency_cycles(int(m))};
}

}  // namespace ropsim
