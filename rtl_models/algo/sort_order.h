// Sample sort order of LK 2011 §4 / Figure 7 line 9: the surviving samples of a
// fragment in increasing order of the depth *already stored* at them; ties are
// broken by sample id, so the order is a total order and every sorter variant
// (bitonic, rank, serial) must produce exactly this permutation.
#pragma once
#include <algorithm>
#include <climits>
#include <cstdint>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

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

/// The same order as sort_keys, computed by grouping the samples by stored
/// depth: a pixel holds few distinct depths (one per visible surface), so this
/// is O(m x distinct) instead of O(m^2). Writes the sample ids to order[0..m)
/// and returns m.
#if defined(__SSE2__)
/// The samples among the first n whose stored depth has the bits v, four
/// compares at a time.
inline uint64_t same_depth_mask(const float* stored, int n, uint32_t v) {
  const __m128i vv = _mm_set1_epi32(static_cast<int>(v));
  uint64_t eq = 0;
  int i = 0;
  for (; i + 4 <= n; i += 4) {
    const __m128i z = _mm_loadu_si128(reinterpret_cast<const __m128i*>(stored + i));
    eq |= uint64_t(uint32_t(_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(z, vv))))) << i;
  }
  for (; i < n; ++i) eq |= uint64_t(depth_bits(stored[i]) == v) << i;
  return eq;
}

/// The rank sort of up to 16 samples: each sample's place is the number of
/// samples whose key is smaller (a smaller stored depth, or the same and a
/// smaller sample id), four compares at a time, without a branch on the data.
inline int sort_by_rank16(const float* stored, uint64_t samples, uint8_t* order) {
  alignas(16) int32_t z[16];
  alignas(16) uint8_t ids[16];
  int m = 0;
  for (uint64_t s = samples; s; s &= s - 1) {
    const int id = __builtin_ctzll(s);
    ids[m] = static_cast<uint8_t>(id);
    z[m++] = static_cast<int32_t>(depth_bits(stored[id]));  // depth >= +0: below 2^31, signed compares order it
  }
  const int blocks = (m + 3) >> 2;
  for (int i = m; i < 4 * blocks; ++i) z[i] = INT32_MAX;  // above every depth (+inf is 0x7f800000)
  for (int i = 0; i < m; ++i) {
    const __m128i zi = _mm_set1_epi32(z[i]);
    int rank = 0;
    for (int b = 0; b < blocks; ++b) {
      const __m128i zb = _mm_load_si128(reinterpret_cast<const __m128i*>(z + 4 * b));
      const int lt = _mm_movemask_ps(_mm_castsi128_ps(_mm_cmpgt_epi32(zi, zb)));
      const int eq = _mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(zi, zb)));
      const int before = i - 4 * b;  // samples of this block with a smaller id than sample i
      const int low = before >= 4 ? 0xF : before <= 0 ? 0 : (1 << before) - 1;
      rank += __builtin_popcount(static_cast<unsigned>(lt)) + __builtin_popcount(static_cast<unsigned>(eq & low));
    }
    order[rank] = ids[i];
  }
  return m;
}
#endif

inline int sort_by_stored_depth(const float* stored, uint64_t samples, uint8_t* order) {
  uint32_t vals[64];
  uint64_t masks[64];
  int d = 0;
#if defined(__SSE2__)
  // One group per distinct depth, each found four samples at a time (only
  // samples below the highest one in `samples` are read: stored holds at
  // least that many). The common case first: one group holds every sample (a
  // pixel still clear, or covered by one surface), and the order is the ids'.
  const int n = samples ? 64 - __builtin_clzll(samples) : 0;
  for (uint64_t rest = samples; rest;) {
    const uint32_t v = depth_bits(stored[__builtin_ctzll(rest)]);
    const uint64_t eq = same_depth_mask(stored, n, v) & rest;
    // Several depths among up to 16 samples: the rank sort.
    if (d == 0 && eq != samples && __builtin_popcountll(samples) <= 16) return sort_by_rank16(stored, samples, order);
    vals[d] = v;
    masks[d++] = eq;
    rest &= ~eq;
  }
#else
  for (uint64_t s = samples; s; s &= s - 1) {
    const uint32_t v = depth_bits(stored[__builtin_ctzll(s)]);
    const uint64_t bit = s & (~s + 1);
    int j = 0;
    while (j < d && vals[j] != v) ++j;
    if (j == d) {
      vals[d] = v;
      masks[d++] = bit;
    } else {
      masks[j] |= bit;
    }
  }
#endif
  for (int i = 1; i < d; ++i) {  // insertion sort of the distinct depths
    const uint32_t v = vals[i];
    const uint64_t mk = masks[i];
    int j = i - 1;
    while (j >= 0 && vals[j] > v) {
      vals[j + 1] = vals[j];
      masks[j + 1] = masks[j];
      --j;
    }
    vals[j + 1] = v;
    masks[j + 1] = mk;
  }
  int m = 0;
  for (int j = 0; j < d; ++j)
    for (uint64_t s = masks[j]; s; s &= s - 1) order[m++] = static_cast<uint8_t>(__builtin_ctzll(s));
  return m;
}

}  // namespace ropsim
