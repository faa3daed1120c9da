// The ROP cache and the DRAM model driven directly, row by row: each row an
// access sequence and the completion cycles, hits and DRAM traffic it must
// give, written as formulas of the default design's parameters (HwConfig).
// Timing boundaries are probed on both sides: one cycle early and on time.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "rtl_models/algo/bits.h"
#include "rtl_models/config/hw_config.h"
#include "rtl_models/memory/dram.h"
#include "rtl_models/memory/line_set.h"
#include "rtl_models/memory/rop_cache.h"

using namespace ropsim;

namespace {

const HwConfig kHw{};                       // the default design
const HwConfig::Cache& kCache = kHw.cache;  // 64 KiB, 64-byte lines, 8 ways
const HwConfig::Dram& kDram = kHw.dram;

// DRAM timing of one cache line, from an idle channel.
const uint64_t kBurst = ceil_div(uint64_t(kCache.line_bytes), uint64_t(kDram.bytes_per_clock));  // data-bus cycles
const uint64_t kRowMiss = kDram.row_miss_cycles;  // precharge + activate, in the bank
const uint64_t kLatency = kDram.latency_cycles;   // a read's data after its burst
const uint64_t kHit = kCache.hit_latency_cycles;
// A line read from a bank with no open row (or another row open), idle bus.
const uint64_t kFill = kRowMiss + kBurst + kLatency;
// A line written to a bank with no open row, idle bus (no read latency).
const uint64_t kWriteBack = kRowMiss + kBurst;

// ------------------------------------------------------------ DRAM address map

// Addresses of the depth buffer (the buffer bits 48 and up are 0) in the
// channel-interleaved layout: the granule index g = addr / interleave_bytes
// picks channel (g ^ g >> 7 ^ g >> 17) mod channels; the channel's local
// bytes (g / channels) * interleave + addr mod interleave are cut into rows
// of row_bytes, and a row's bank is row mod banks (folded with the buffer).
const uint64_t kNextChannel = kDram.interleave_bytes;                                 // granule 1
const uint64_t kSameRow = uint64_t(kDram.interleave_bytes) * kDram.channels;          // channel 0's next granule
const uint64_t kNextBank = uint64_t(kDram.row_bytes) * kDram.channels;                // channel 0, row 1, bank 1
const uint64_t kSameBank = uint64_t(kDram.row_bytes) * kDram.channels * kDram.banks;  // channel 0, row banks, bank 0
const uint64_t kOtherBuffer = AddressMap::base(Buffer::kColor);  // 2^48: folded into channel and bank

const uint64_t kOtherRow =
    kOtherBuffer / kDram.interleave_bytes / kDram.channels * kDram.interleave_bytes / kDram.row_bytes;

struct MapRow {
  const char* what;
  uint64_t addr;
  size_t channel;
  uint64_t row, bank;
};

TEST(DramTable, AddressMapPlacesEachAddress) {
  const MapRow rows[] = {
      {"address 0: channel 0, row 0, bank 0", 0, 0, 0, 0},
      {"within the first granule: the same place", kDram.interleave_bytes - 1, 0, 0, 0},
      {"the next granule: the next channel", kNextChannel, 1, 0, 0},
      {"the last channel's first granule", uint64_t(kDram.interleave_bytes) * (kDram.channels - 1), kDram.channels - 1,
       0, 0},
      {"channels granules on: channel 0 again, the same row", kSameRow, 0, 0, 0},
      {"a row of channel-local bytes on: the next row, in the next bank", kNextBank, 0, 1, 1},
      {"banks rows on: the same bank, another row", kSameBank, 0, kDram.banks, 0},
      // Its granule index g is 2^48 / interleave; its channel-local bytes (g / channels) * interleave.
      {"the colour buffer's address 0: the buffer bits fold into channel and bank", kOtherBuffer, 1 % kDram.channels,
       kOtherRow, (kOtherRow ^ 1) % kDram.banks},
  };
  const DramAddressMap map(kDram);
  for (const MapRow& r : rows) {
    SCOPED_TRACE(r.what);
    const DramAddressMap::Place p = map.place(r.addr);
    EXPECT_EQ(p.channel, r.channel);
    EXPECT_EQ(map.channel_of(r.addr), r.channel);
    EXPECT_EQ(p.row, r.row);
    EXPECT_EQ(p.bank, r.bank);
  }
}

// ------------------------------------------------------------ DRAM timing

struct DramAccess {
  uint64_t addr;
  uint32_t bytes;
  bool write;
  uint64_t at;    // the cycle it is issued
  uint64_t done;  // the cycle access() must return
  Buffer buf = Buffer::kDepth;
};

struct DramWant {
  uint64_t row_hits, row_misses;
  uint64_t depth_read, depth_written, color_read;  // bytes
  uint64_t busy;                                   // data-bus cycles, every channel
};

struct DramRow {
  const char* what;
  std::vector<DramAccess> seq;
  DramWant want;
};

TEST(DramTable, RowStatesTimingBoundariesAndBytes) {
  const uint64_t L = kCache.line_bytes, B = kBurst, M = kRowMiss, R = kLatency;
  // A first read of address 0 at cycle 0 holds its bank and the channel's bus
  // until M + B: the boundary of the rows below.
  const uint64_t free_at = M + B;
  // want: {row hits, row misses, depth bytes read, depth bytes written, colour bytes read, bus cycles}
  const DramRow rows[] = {
      {"an empty bank: a read pays the row switch, the burst and the latency",
       {{0, uint32_t(L), false, 0, M + B + R}},
       {0, 1, L, 0, 0, B}},
      {"an empty bank: a write completes at its burst's end (no latency)",
       {{0, uint32_t(L), true, 0, M + B}},
       {0, 1, 0, L, 0, B}},
      {"the open row: a row hit pays only the burst and the latency",
       {{0, uint32_t(L), false, 0, M + B + R}, {kSameRow, uint32_t(L), false, 1000, 1000 + B + R}},
       {1, 1, 2 * L, 0, 0, 2 * B}},
      {"another row open in the bank (a conflict): the same row switch as an empty bank",
       {{0, uint32_t(L), false, 0, M + B + R}, {kSameBank, uint32_t(L), false, 1000, 1000 + M + B + R}},
       {0, 2, 2 * L, 0, 0, 2 * B}},
      {"a row hit arriving one cycle before its bank is free waits the cycle",
       {{0, uint32_t(L), false, 0, M + B + R}, {kSameRow, uint32_t(L), false, free_at - 1, free_at + B + R}},
       {1, 1, 2 * L, 0, 0, 2 * B}},
      {"a row hit arriving when its bank is free starts at once",
       {{0, uint32_t(L), false, 0, M + B + R}, {kSameRow, uint32_t(L), false, free_at, free_at + B + R}},
       {1, 1, 2 * L, 0, 0, 2 * B}},
      {"a conflict arriving one cycle before its bank is free switches rows a cycle late",
       {{0, uint32_t(L), false, 0, M + B + R}, {kSameBank, uint32_t(L), false, free_at - 1, free_at + M + B + R}},
       {0, 2, 2 * L, 0, 0, 2 * B}},
      {"a conflict arriving when its bank is free switches rows at once",
       {{0, uint32_t(L), false, 0, M + B + R}, {kSameBank, uint32_t(L), false, free_at, free_at + M + B + R}},
       {0, 2, 2 * L, 0, 0, 2 * B}},
      // Another bank of the channel switches rows while the first bank's
      // burst holds the bus: its switch ends at at + M, its burst starts when
      // the bus is free too (M + B).
      {"another bank whose row switch ends one cycle before the bus is free waits for the bus",
       {{0, uint32_t(L), false, 0, M + B + R}, {kNextBank, uint32_t(L), false, B - 1, free_at + B + R}},
       {0, 2, 2 * L, 0, 0, 2 * B}},
      {"another bank whose row switch ends when the bus is free: its switch hidden by the first burst",
       {{0, uint32_t(L), false, 0, M + B + R}, {kNextBank, uint32_t(L), false, B, B + M + B + R}},
       {0, 2, 2 * L, 0, 0, 2 * B}},
      {"another channel at the same cycle: independent, the same timing",
       {{0, uint32_t(L), false, 0, M + B + R}, {kNextChannel, uint32_t(L), false, 0, M + B + R}},
       {0, 2, 2 * L, 0, 0, 2 * B}},
      {"a write then a read of its row: the read hits the row the write opened",
       {{0, uint32_t(L), true, 0, M + B}, {kSameRow, uint32_t(L), false, free_at, free_at + B + R}},
       {1, 1, L, L, 0, 2 * B}},
      {"bytes of one bus width: one bus cycle",
       {{0, kDram.bytes_per_clock, false, 0, M + 1 + R}},
       {0, 1, kDram.bytes_per_clock, 0, 0, 1}},
      {"one byte over a bus width: a second bus cycle, the bytes counted as asked",
       {{0, kDram.bytes_per_clock + 1, false, 0, M + 2 + R}},
       {0, 1, kDram.bytes_per_clock + 1, 0, 0, 2}},
      {"the colour buffer's bytes are counted as colour",
       {{kOtherBuffer, uint32_t(L), false, 0, M + B + R, Buffer::kColor}},
       {0, 1, 0, 0, L, B}},
  };
  for (const DramRow& r : rows) {
    SCOPED_TRACE(r.what);
    Dram dram(kDram);
    for (size_t i = 0; i < r.seq.size(); ++i) {
      const DramAccess& a = r.seq[i];
      EXPECT_EQ(dram.access(a.addr, a.bytes, a.write, a.buf, a.at), a.done) << "access " << i;
    }
    const DramStats s = dram.stats();
    EXPECT_EQ(s.row_hits, r.want.row_hits);
    EXPECT_EQ(s.row_misses, r.want.row_misses);
    EXPECT_EQ(s.bytes_read[size_t(Buffer::kDepth)], r.want.depth_read);
    EXPECT_EQ(s.bytes_written[size_t(Buffer::kDepth)], r.want.depth_written);
    EXPECT_EQ(s.bytes_read[size_t(Buffer::kColor)], r.want.color_read);
    EXPECT_EQ(s.total_bytes_read() + s.total_bytes_written(),
              r.want.depth_read + r.want.depth_written + r.want.color_read);
    EXPECT_EQ(s.busy_cycles, r.want.busy);
    uint64_t last = 0;
    for (const DramAccess& a : r.seq) last = std::max(last, a.done);
    EXPECT_EQ(s.last_completion, last);
  }
}

// ------------------------------------------------------------ ROP cache

// Lines k * stride (k < 2048 / sets) of the depth buffer share set 0: the set
// index is the line index folded with its bits 11 and up (cache_tags.h).
const uint64_t kSets = kCache.size_bytes / (uint64_t(kCache.line_bytes) * kCache.ways);
const uint64_t kStride = kSets * kCache.line_bytes;
uint64_t same_set(uint64_t k) { return k * kStride; }

// kPost: a writeback unit's posted write (PostedWrites), applied before any
// access at a later cycle.
enum class Op { kRead, kWrite, kPost, kFlush };

struct CacheAccess {
  Op op;
  uint64_t line;
  uint64_t at;
  uint64_t done = 0;  // the cycle read() or flush() must return (writes and posts return nothing)
};

struct CacheWant {
  uint64_t read_hits, read_misses, write_misses, merged, evictions, dirty_evictions, clear_fills;
  uint64_t dram_read, dram_written;  // bytes
  uint64_t dram_last;                // DramStats::last_completion: when the last DRAM access ends
};

struct CacheSetup {
  bool fast_clear;
  bool in_dram;  // DRAM holds line A (it was written back before the sequence)
};

struct CacheRow {
  const char* what;
  CacheSetup setup;
  std::vector<CacheAccess> seq;
  CacheWant want;
};

/// Reads of lines same_set(first) .. same_set(first + n - 1), one a cycle from `at`, each a fast-clear fill.
std::vector<CacheAccess> clear_reads(uint64_t first, uint64_t n, uint64_t at) {
  std::vector<CacheAccess> v;
  for (uint64_t k = 0; k < n; ++k) v.push_back({Op::kRead, same_set(first + k), at + k, at + k + kHit});
  return v;
}

std::vector<CacheAccess> cat(std::vector<CacheAccess> a, const std::vector<CacheAccess>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

TEST(RopCacheTable, HitsMissesMergesEvictionsAndFastClear) {
  ASSERT_LT((kCache.ways + 1) * kSets, 2048u) << "the same-set lines must stay below line bit 11";
  const uint64_t A = same_set(0), L = kCache.line_bytes, W = kCache.ways;
  // With fast_clear off, or the line in DRAM: A's fill from an idle DRAM.
  const uint64_t a_ready = kFill + kHit;
  // The eviction rows fill set 0's ways after A with clear fills (no DRAM
  // traffic), from cycle 1; the read of way W + 1 evicts A, the LRU line, at
  // cycle W.
  const uint64_t evict_at = W;
  // setup: {fast_clear, A in DRAM}; seq: {op, line, cycle, completion};
  // want: {read hits, read misses, write misses, merged, evictions, dirty
  // evictions, clear fills, DRAM bytes read, DRAM bytes written, DRAM's last completion}
  const CacheRow rows[] = {
      {"a miss with the line in DRAM: the fill, then the hit latency",
       {true, true},
       {{Op::kRead, A, 0, kFill + kHit}},
       {0, 1, 0, 0, 0, 0, 0, L, 0, kFill}},
      {"a miss without fast clear: the same DRAM fill",
       {false, false},
       {{Op::kRead, A, 0, kFill + kHit}},
       {0, 1, 0, 0, 0, 0, 0, L, 0, kFill}},
      {"fast clear: a miss of a line never written to DRAM is a clear fill at hit latency, no DRAM read",
       {true, false},
       {{Op::kRead, A, 0, kHit}},
       {0, 1, 0, 0, 0, 0, 1, 0, 0, 0}},
      {"a hit after the fill: the hit latency",
       {false, false},
       {{Op::kRead, A, 0, a_ready}, {Op::kRead, A, 1000, 1000 + kHit}},
       {1, 1, 0, 0, 0, 0, 0, L, 0, kFill}},
      {"a read while the fill is in flight merges: it completes with the fill, one DRAM read",
       {false, false},
       {{Op::kRead, A, 0, a_ready}, {Op::kRead, A, 10, a_ready}},
       {1, 1, 0, 1, 0, 0, 0, L, 0, kFill}},
      {"a read one cycle before the fill's data would be late at hit latency: merged",
       {false, false},
       {{Op::kRead, A, 0, a_ready}, {Op::kRead, A, a_ready - kHit - 1, a_ready}},
       {1, 1, 0, 1, 0, 0, 0, L, 0, kFill}},
      {"a read whose hit latency ends when the fill's data is there: a plain hit",
       {false, false},
       {{Op::kRead, A, 0, a_ready}, {Op::kRead, A, a_ready - kHit, a_ready}},
       {1, 1, 0, 0, 0, 0, 0, L, 0, kFill}},
      {"write allocate: a write miss takes a way without a fill; a read of it hits at hit latency",
       {false, false},
       {{Op::kWrite, A, 0}, {Op::kRead, A, 5, 5 + kHit}},
       {1, 0, 1, 0, 0, 0, 0, 0, 0, 0}},
      {"a clean eviction: a set's (ways + 1)-th line evicts the LRU one, no write-back",
       {true, false},
       clear_reads(0, W + 1, 0),
       {0, W + 1, 0, 0, 1, 0, W + 1, 0, 0, 0}},
      {"a dirty eviction: the victim is written back when it leaves; the evicting read is not delayed",
       {true, false},
       cat({{Op::kWrite, A, 0}}, clear_reads(1, W, 1)),
       {0, W, 1, 0, 1, 1, W, 0, L, evict_at + kWriteBack}},
      {"the victim's line read again: a DRAM fill that hits the row its write-back opened",
       {true, false},
       cat(cat({{Op::kWrite, A, 0}}, clear_reads(1, W, 1)), {{Op::kRead, A, 1000, 1000 + kBurst + kLatency + kHit}}),
       {0, W + 1, 1, 0, 2, 1, W, L, L, 1000 + kBurst + kLatency}},
      {"a flush writes the dirty lines back and returns the last write's end",
       {true, false},
       {{Op::kWrite, A, 0}, {Op::kFlush, 0, 100, 100 + kWriteBack}},
       {0, 0, 1, 0, 0, 0, 0, 0, L, 100 + kWriteBack}},
      {"a flush of clean lines writes nothing and returns its cycle",
       {false, false},
       {{Op::kRead, A, 0, a_ready}, {Op::kFlush, 0, 1000, 1000}},
       {0, 1, 0, 0, 0, 0, 0, L, 0, kFill}},
      {"a read in the cycle of a posted write does not see it: a miss",
       {true, false},
       {{Op::kPost, A, 10}, {Op::kRead, A, 10, 10 + kHit}},
       {0, 1, 0, 0, 0, 0, 1, 0, 0, 0}},
      {"a read one cycle after a posted write sees it: the write allocated the line, a hit",
       {true, false},
       {{Op::kPost, A, 10}, {Op::kRead, A, 11, 11 + kHit}},
       {1, 0, 1, 0, 0, 0, 0, 0, 0, 0}},
  };
  for (const CacheRow& r : rows) {
    SCOPED_TRACE(r.what);
    HwConfig::Cache cfg = kCache;
    cfg.fast_clear = r.setup.fast_clear;
    Dram dram(kDram);
    LineSet in_dram(cfg.line_bytes);
    if (r.setup.in_dram) in_dram.insert(same_set(0));
    PostedWrites posted;
    RopCache cache(cfg, dram, in_dram, &posted);
    for (size_t i = 0; i < r.seq.size(); ++i) {
      const CacheAccess& a = r.seq[i];
      switch (a.op) {
        case Op::kRead:
          EXPECT_EQ(cache.read(a.line, Buffer::kDepth, a.at), a.done) << "access " << i << " (a read)";
          break;
        case Op::kWrite:
          cache.write(a.line, Buffer::kDepth, a.at);
          break;
        case Op::kPost:
          cache.post_write(a.line, Buffer::kDepth, a.at);
          break;
        case Op::kFlush:
          EXPECT_EQ(cache.flush(a.at), a.done) << "access " << i << " (the flush)";
          break;
      }
    }
    const CacheStats& s = cache.stats();
    const size_t d = size_t(Buffer::kDepth);
    EXPECT_EQ(s.read_hits[d], r.want.read_hits);
    EXPECT_EQ(s.read_misses[d], r.want.read_misses);
    EXPECT_EQ(s.write_misses[d], r.want.write_misses);
    EXPECT_EQ(s.merged, r.want.merged);
    EXPECT_EQ(s.evictions, r.want.evictions);
    EXPECT_EQ(s.dirty_evictions, r.want.dirty_evictions);
    EXPECT_EQ(s.clear_fills, r.want.clear_fills);
    const DramStats ds = dram.stats();
    EXPECT_EQ(ds.total_bytes_read(), r.want.dram_read);
    EXPECT_EQ(ds.total_bytes_written(), r.want.dram_written);
    EXPECT_EQ(ds.last_completion, r.want.dram_last);
  }
}

}  // namespace
