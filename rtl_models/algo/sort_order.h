// Sample sort order of LK 2011 §4 / Figure 7 line 9: the surviving samples of a
// fragment in increasing order of the depth *already stored* at them; ties are
// broken by sample id, so the order is a total order and every sorter variant
// (bitonic, rank, serial) must produce exactly this permutation.
#pragma once
#include <algorithm>
#include <climits>
#include <cstdint>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "rtl_models/algo/bits.h"
#include "rtl_models/algo/depth.h"

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
/// is O(m x distinct) instead of O(m^2); samples all within the first 16 are
/// ranked instead (sort_low16). Writes the sample ids to order[0..m) and
/// returns m; order has room for 64 ids, and order[m..16) may be overwritten.
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

namespace sort_detail {
/// at_or_before[j][i]: 1 if lane i <= j, else 0 (16 lanes per row).
struct LaneTable {
  alignas(16) int32_t at_or_before[16][16];
};

constexpr LaneTable make_lane_table() {
  LaneTable t{};
  for (int j = 0; j < 16; ++j)
    for (int i = 0; i < 16; ++i) t.at_or_before[j][i] = i <= j ? 1 : 0;
  return t;
}

inline constexpr LaneTable kLanes = make_lane_table();

/// byte_ids[b]: the positions of b's set bits, ascending, one per byte from
/// the lowest (the bytes past popcount(b) are 0).
struct ByteIdTable {
  uint64_t byte_ids[256];
};

constexpr ByteIdTable make_byte_id_table() {
  ByteIdTable t{};
  for (int b = 0; b < 256; ++b) {
    int k = 0;
    for (int i = 0; i < 8; ++i)
      if (b >> i & 1) t.byte_ids[b] |= uint64_t(i) << (8 * k++);
  }
  return t;
}

inline constexpr ByteIdTable kByteIds = make_byte_id_table();

/// The ids of samples (below 2^16) in ascending order into order[0..m),
/// eight bytes per mask byte (order[m..16) may be overwritten); returns m.
inline int ids_in_order(uint64_t samples, uint8_t* order) {
  const uint32_t lo = uint32_t(samples) & 0xFFu, hi = uint32_t(samples >> 8) & 0xFFu;
  const int m = __builtin_popcount(lo);
  const uint64_t lo_ids = kByteIds.byte_ids[lo], hi_ids = kByteIds.byte_ids[hi] + 0x0808080808080808ull;
  std::memcpy(order, &lo_ids, 8);
  std::memcpy(order + m, &hi_ids, 8);
  return m + __builtin_popcount(hi);
}
}  // namespace sort_detail

/// Ranks by (key, lane) among the lanes of `lanes` (a mask of lanes below
/// 4 kBlocks <= 16; z: 4 kBlocks keys in [0, 2^31 - 1)): for each lane i of
/// `lanes`, rank[i] = the number of lanes j of `lanes` with z[j] < z[i], or
/// z[j] == z[i] and j < i. Other lanes' ranks are not meaningful. Column by
/// column: for each j, every lane i at once counts the j it does not follow,
/// z[i] <= z[j] - 1 where i > j and z[i] <= z[j] where i <= j (as z[j] + 1 or
/// z[j] > z[i]), four lanes per compare, no branch on the data.
template <int kBlocks>
inline void rank_lanes(const int32_t* z, uint64_t lanes, int32_t* rank) {
  __m128i zb[kBlocks], not_after[kBlocks];
  for (int b = 0; b < kBlocks; ++b) {
    zb[b] = _mm_load_si128(reinterpret_cast<const __m128i*>(z + 4 * b));
    not_after[b] = _mm_setzero_si128();  // minus the count
  }
  for (uint64_t s = lanes; s; s &= s - 1) {
    const int j = __builtin_ctzll(s);
    const __m128i zj = _mm_set1_epi32(z[j]);
    const __m128i* up = reinterpret_cast<const __m128i*>(sort_detail::kLanes.at_or_before[j]);
    for (int b = 0; b < kBlocks; ++b)
      not_after[b] = _mm_add_epi32(not_after[b], _mm_cmpgt_epi32(_mm_add_epi32(zj, _mm_load_si128(up + b)), zb[b]));
  }
  const __m128i m = _mm_set1_epi32(__builtin_popcountll(lanes));
  for (int b = 0; b < kBlocks; ++b)
    _mm_store_si128(reinterpret_cast<__m128i*>(rank + 4 * b), _mm_add_epi32(m, not_after[b]));
}

/// rank_lanes over blocks (1 to 4) blocks of four lanes.
inline void rank_lanes(int blocks, const int32_t* z, uint64_t lanes, int32_t* rank) {
  switch (blocks) {
    case 1:
      return rank_lanes<1>(z, lanes, rank);
    case 2:
      return rank_lanes<2>(z, lanes, rank);
    case 3:
      return rank_lanes<3>(z, lanes, rank);
    default:
      return rank_lanes<4>(z, lanes, rank);
  }
}

/// The sort of samples within the first 16 (samples != 0): one lane per
/// sample id, the stored depths loaded four at a time (only samples below
/// the highest in `samples` are read). One depth at every sample: the order
/// is the ids'; several: the rank sort (rank_lanes).
inline int sort_low16(const float* stored, uint64_t samples, uint8_t* order) {
  alignas(16) int32_t z[16];
  alignas(16) int32_t rank[16];
  const int n = 64 - __builtin_clzll(samples), blocks = (n + 3) >> 2;
  int i = 0;
  for (; i + 4 <= n; i += 4)
    _mm_store_si128(reinterpret_cast<__m128i*>(z + i), _mm_loadu_si128(reinterpret_cast<const __m128i*>(stored + i)));
  for (; i < n; ++i) z[i] = static_cast<int32_t>(depth_bits(stored[i]));  // depth >= +0: below 2^31
  for (; i < 4 * blocks; ++i) z[i] = INT32_MAX;                           // padding, never ranked
  const __m128i v = _mm_set1_epi32(z[__builtin_ctzll(samples)]);
  uint64_t same = 0;
  for (int b = 0; b < blocks; ++b)
    same |= uint64_t(uint32_t(_mm_movemask_ps(
                _mm_castsi128_ps(_mm_cmpeq_epi32(_mm_load_si128(reinterpret_cast<const __m128i*>(z + 4 * b)), v)))))
            << (4 * b);
  if ((same & samples) == samples) return sort_detail::ids_in_order(samples, order);
  int m = 0;
  rank_lanes(blocks, z, samples, rank);
  for (uint64_t s = samples; s; s &= s - 1) {
    const int id = __builtin_ctzll(s);
    order[rank[id]] = static_cast<uint8_t>(id);
    ++m;
  }
  return m;
}

/// The rank sort of up to 16 samples anywhere among 64: their stored depths
/// gathered into lanes 0..m-1 in id order (so the lane order is the ids'),
/// then rank_lanes.
inline int sort_by_rank16(const float* stored, uint64_t samples, uint8_t* order) {
  alignas(16) int32_t z[16];
  alignas(16) int32_t rank[16];
  alignas(16) uint8_t ids[16];
  int m = 0;
  for (uint64_t s = samples; s; s &= s - 1) {
    const int id = __builtin_ctzll(s);
    ids[m] = static_cast<uint8_t>(id);
    z[m++] = static_cast<int32_t>(depth_bits(stored[id]));  // depth >= +0: below 2^31, signed compares order it
  }
  const int blocks = (m + 3) >> 2;
  for (int i = m; i < 4 * blocks; ++i) z[i] = INT32_MAX;  // padding, never ranked
  rank_lanes(blocks, z, low_mask(m), rank);
  for (int i = 0; i < m; ++i) order[rank[i]] = ids[i];
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
  if (samples == 0) return 0;
  if (samples >> 16 == 0) return sort_low16(stored, samples, order);
  const int n = 64 - __builtin_clzll(samples);
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
