// Sample sorter (lk only): orders the surviving samples by the depth already
// stored at them (LK Figure 7 line 9), with the variant chosen in the config
// (sorter/sort_algorithm.h: bitonic, rank or serial). The variant sets the
// latency and initiation interval. The permutation is computed once, by the
// shared sort_by_stored_depth of sort_order.h, which the tests prove equal to
// each variant's own network on random and tied keys: running a 16-wide
// bitonic network in software per fragment would cost time and show nothing.
#pragma once
#include <memory>

#include "rtl_models/config/hw_config.h"
#include "rtl_models/core/pipe_unit.h"
#include "rtl_models/sorter/sort_algorithm.h"

namespace ropsim {

class SampleSorter : public PipeUnit {
 public:
  SampleSorter(const sc_core::sc_module_name& name, const Clock& clk, FunctionalRop& rop,
               std::unique_ptr<SortAlgorithm> algo, TokenFifo& in, TokenFifo& out)
      : PipeUnit(name, clk, rop, in, out), algo_(std::move(algo)) {}
  const SortAlgorithm& algorithm() const { return *algo_; }
  std::vector<Extra> extras() const override {
    return {{"comparators", double(algo_->comparators()), "comparators",
             "two-input comparators of the sorter variant (area proxy)"},
            {"latency_cycles", double(algo_->latency_cycles(algo_->width())), "cycles",
             "the sorter variant's latency for a full pixel"}};
  }

 protected:
  Timing process(FragToken* t, uint64_t now) override;

 private:
  std::unique_ptr<SortAlgorithm> algo_;
};

}  // namespace ropsim
