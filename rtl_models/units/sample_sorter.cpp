#include "sample_sorter.h"

#include "sort_order.h"

namespace ropsim {

PipeUnit::Timing SampleSorter::process(FragToken* t, uint64_t) {
  // The order is sort_order.h's, which every variant's network produces
  // (SortVariants tests); the variant supplies the timing.
  const int m = sort_by_stored_depth(t->px.depth, t->survivors, t->order);
  ctx_.counters.sorts += m > 1;
  stats_.samples += uint64_t(m);
  return {algo_->interval_cycles(m), algo_->latency_cycles(m)};
}

}  // namespace ropsim
