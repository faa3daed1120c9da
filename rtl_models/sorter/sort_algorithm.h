// Sample-sorter variants (LK 2011 Figure 7 line 9): an interface, one file per
// variant, and an explicit factory. Each variant really runs its algorithm on
// the sort keys of sort_order.h, so a test can check that every variant gives
// the permutation of sort_keys(); the timing methods give the SystemC sorter
// its latency and initiation interval. No SystemC here.
#pragma once
#include <cstdint>
#include <memory>

#include "rtl_models/config/hw_config.h"

namespace ropsim {

class SortAlgorithm {
 public:
  explicit SortAlgorithm(int width) : width_(width) {}
  virtual ~SortAlgorithm() = default;
  virtual const char* name() const = 0;
  /// Sorts keys[0..m) ascending, m <= width(); keys are unique.
  virtual void sort(uint64_t* keys, int m) const = 0;
  /// Cycles from accepting a fragment with m samples to its sorted output.
  virtual uint32_t latency_cycles(int m) const = 0;
  /// Cycles before the next fragment can be accepted.
  virtual uint32_t interval_cycles(int m) const = 0;
  /// Two-input comparators in the datapath (an area proxy for the report).
  virtual uint64_t comparators() const = 0;
  /// Network width N: the samples per pixel it is built for.
  int width() const { return width_; }

 protected:
  int width_;
};

std::unique_ptr<SortAlgorithm> make_bitonic_sorter(int width);
std::unique_ptr<SortAlgorithm> make_rank_sorter(int width);
std::unique_ptr<SortAlgorithm> make_serial_sorter(int width);

/// The factory: a sorter of the given kind for N = width samples.
std::unique_ptr<SortAlgorithm> make_sorter(SorterKind kind, int width);

}  // namespace ropsim
