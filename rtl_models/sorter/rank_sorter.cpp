// Rank sorter: every key is compared with every other (N (N - 1) / 2
// comparators); a key's rank is the number of smaller keys and selects its
// output position. One clock, one fragment per clock.
#include "rtl_models/sorter/sort_algorithm.h"

namespace ropsim {
namespace {

class RankSorter final : public SortAlgorithm {
 public:
  using SortAlgorithm::SortAlgorithm;
  const char* name() const override { return "rank"; }
  void sort(uint64_t* keys, int m) const override {
    uint64_t out[64];
    for (int i = 0; i < m; ++i) {
      int rank = 0;
      for (int j = 0; j < m; ++j) rank += keys[j] < keys[i];
      out[rank] = keys[i];
    }
    for (int i = 0; i < m; ++i) keys[i] = out[i];
  }
  uint32_t latency_cycles(int) const override { return 1; }
  uint32_t interval_cycles(int) const override { return 1; }
  uint64_t comparators() const override { return uint64_t(width_) * uint64_t(width_ - 1) / 2; }
};

}  // namespace

std::unique_ptr<SortAlgorithm> make_rank_sorter(int width) { return std::make_unique<RankSorter>(width); }

}  // namespace ropsim
