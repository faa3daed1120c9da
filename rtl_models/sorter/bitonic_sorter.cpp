// Bitonic sorting network of width N = 2^k (Batcher 1968): k (k + 1) / 2
// stages of N / 2 compare-exchange elements, one stage per clock, fully
// pipelined. Unused inputs hold the largest key and sink to the end.
#include <algorithm>

#include "rtl_models/algo/bits.h"
#include "rtl_models/sorter/sort_algorithm.h"

namespace ropsim {
namespace {

class BitonicSorter final : public SortAlgorithm {
 public:
  explicit BitonicSorter(int width) : SortAlgorithm(width), k_(log2_ceil(unsigned(width))) {}
  const char* name() const override { return "bitonic"; }
  void sort(uint64_t* keys, int m) const override {
    const int n = 1 << k_;
    uint64_t v[64];
    for (int i = 0; i < n; ++i) v[i] = i < m ? keys[i] : ~uint64_t{0};
    for (int size = 2; size <= n; size <<= 1)                 // merge phases
      for (int stride = size >> 1; stride > 0; stride >>= 1)  // one stage each
        for (int i = 0; i < n; ++i) {
          const int j = i ^ stride;
          if (j <= i) continue;
          const bool ascending = (i & size) == 0;
          if ((v[i] > v[j]) == ascending) std::swap(v[i], v[j]);
        }
    std::copy(v, v + m, keys);
  }
  uint32_t stages() const { return uint32_t(k_ * (k_ + 1) / 2); }
  uint32_t latency_cycles(int) const override { return std::max(1u, stages()); }
  uint32_t interval_cycles(int) const override { return 1; }
  uint64_t comparators() const override { return uint64_t(stages()) * ((1u << k_) / 2); }

 private:
  int k_;
};

}  // namespace

std::unique_ptr<SortAlgorithm> make_bitonic_sorter(int width) { return std::make_unique<BitonicSorter>(width); }

}  // namespace ropsim
