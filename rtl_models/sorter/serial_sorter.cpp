// Serial insertion sorter: a register array of N entries with a comparator
// each; one key enters per clock and the larger entries shift up. m keys take
// m clocks (at least one), and the unit is busy for all of them.
#include <algorithm>

#include "rtl_models/sorter/sort_algorithm.h"

namespace ropsim {
namespace {

class SerialSorter final : public SortAlgorithm {
 public:
  using SortAlgorithm::SortAlgorithm;
  const char* name() const override { return "serial"; }
  void sort(uint64_t* keys, int m) const override {
    uint64_t reg[64];
    int n = 0;
    for (int i = 0; i < m; ++i) {  // one clock per key
      int j = n++;
      while (j > 0 && reg[j - 1] > keys[i]) {
        reg[j] = reg[j - 1];
        --j;
      }
      reg[j] = keys[i];
    }
    std::copy(reg, reg + m, keys);
  }
  uint32_t latency_cycles(int m) const override { return uint32_t(std::max(1, m)); }
  uint32_t interval_cycles(int m) const override { return uint32_t(std::max(1, m)); }
  uint64_t comparators() const override { return uint64_t(width_); }
};

}  // namespace

std::unique_ptr<SortAlgorithm> make_serial_sorter(int width) { return std::make_unique<SerialSorter>(width); }

}  // namespace ropsim
