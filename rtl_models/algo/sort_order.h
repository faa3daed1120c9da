// Sample sort order of LK 2011 §4 / Figure 7 line 9: the surviving samples of a
// fragment in increasing order of the depth *already stored* at them; ties are
// broken by sample id, so the order is a total order and every sorter variant
// (bitonic, rank, serial) must produce exactly this permutation.
#pragma once
#include <algorithm>
#include <cstdint>

#include "depth.h"

namespace ropsim {

/// Sort key: stored depth bits (depth >= +0, so bits order like values) above
/// the 6-bit sample id.
inline uint64_t sort_key(float stored_depth, uint32_t sample_id) {
  return (uint64_t{depth_bits(stored_depth)} << 6) | sample_id;
}
inline uint32_t sort_key_sample(uint64_t key) { return static_cast<uint32_t>(key & 63u); }

/// Sorts keys[0..m) ascending. Keys are unique, so the result does not depend
/// on the algorithm. Insertion sort: m <= 64 and keys are often nearly sorted.
inline void sort_keys(uint64_t* keys, int m) {
  for (int i = 1; i < m; ++i) {
    const uint64_t k = keys[i];
    int j = i - 1;
    if (keys[j] < k) continue;
    while (j >= 0 && keys[j] > k) {
      keys[j + 1] = keys[j];
      --j;
    }
    keys[j + 1] = k;
  }
}

}  // namespace ropsim
