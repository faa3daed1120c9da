// The ring containers (util/containers): RingQueue keeps FIFO order across
// its growth and the ring's wrap; SortedRing pops in ascending order and
// keeps equal entries in push order, across growth and wrap too. Hex
// formatting (util/hex.h) is fixed width.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

#include "util/containers/ring_queue.h"
#include "util/containers/sorted_ring.h"
#include "util/hex.h"

namespace ropsim {
namespace {

TEST(Containers, RingQueueIsFifoAcrossGrowthAndWrap) {
  RingQueue<int> q(4);
  int next_in = 0, next_out = 0;
  // Interleave so that the head wraps before each growth.
  for (int round = 0; round < 6; ++round) {
    for (int i = 0; i < 3 + 5 * round; ++i) q.push_back(next_in++);
    for (int i = 0; i < 2 + 3 * round; ++i) {
      ASSERT_EQ(q.front(), next_out) << "round " << round << ": out of FIFO order";
      q.pop_front();
      ++next_out;
    }
    for (size_t i = 0; i < q.size(); ++i) ASSERT_EQ(q[i], next_out + int(i)) << "index " << i << " from the front";
  }
  EXPECT_EQ(q.size(), size_t(next_in - next_out));
}

struct ByKey {
  bool operator()(const std::pair<int, int>& a, const std::pair<int, int>& b) const { return a.first < b.first; }
};

TEST(Containers, SortedRingPopsAscendingAndEqualKeysInPushOrder) {
  SortedRing<std::pair<int, int>, ByKey> r;
  std::vector<std::pair<int, int>> pushed, popped;
  uint32_t s = 12345;  // fixed LCG: the same sequence every run
  int serial = 0;
  for (int round = 0; round < 40; ++round) {
    for (int i = 0; i < 7; ++i) {
      s = s * 1664525u + 1013904223u;
      // Mostly near the back, sometimes far back; few distinct keys, so ties are common.
      const int key = round * 3 + int((s >> 16) % 8) - ((s >> 28) == 0 ? 6 : 0);
      pushed.emplace_back(key, serial++);
      r.push(pushed.back());
    }
    for (int i = 0; i < 5 && !r.empty(); ++i) {
      popped.push_back(r.front());
      r.pop_front();
    }
  }
  while (!r.empty()) {
    popped.push_back(r.front());
    r.pop_front();
  }
  ASSERT_EQ(popped.size(), pushed.size());
  // Between pops, what is held must leave in (key, push order); the pops as a
  // whole need not be sorted, since later pushes may be smaller. Check each
  // pop was the least (key, serial) among what had been pushed and not popped.
  std::vector<std::pair<int, int>> held;
  size_t pi = 0, oi = 0;
  for (int round = 0; round < 40; ++round) {
    for (int i = 0; i < 7; ++i) held.push_back(pushed[pi++]);
    for (int i = 0; i < 5 && !held.empty(); ++i) {
      const auto least = *std::min_element(held.begin(), held.end());
      ASSERT_EQ(popped[oi], least) << "pop " << oi << " was not the least key, earliest push first";
      held.erase(std::find(held.begin(), held.end(), least));
      ++oi;
    }
  }
  std::sort(held.begin(), held.end());
  for (const auto& h : held) ASSERT_EQ(popped[oi++], h);
}

TEST(Containers, HexIsFixedWidthLowerCase) {
  EXPECT_EQ(hex64(0xABCull), "0000000000000abc");
  EXPECT_EQ(hex64(~0ull), "ffffffffffffffff");
  EXPECT_EQ(hex32(0x1Fu), "0000001f");
}

}  // namespace
}  // namespace ropsim
