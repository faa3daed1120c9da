#include "rtl_models/sorter/sort_algorithm.h"

namespace ropsim {

std::unique_ptr<SortAlgorithm> make_sorter(SorterKind kind, int width) {
  switch (kind) {
    case SorterKind::kBitonic:
      return make_bitonic_sorter(width);
    case SorterKind::kRank:
      return make_rank_sorter(width);
    case SorterKind::kSerial:
      return make_serial_sorter(width);
  }
  return nullptr;
}

}  // namespace ropsim
