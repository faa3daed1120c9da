// The analytical model's tag-only compression and Hi-Z bookkeeping
// (rtl_models/memory/tag_compression.h) against the rules of the cycle model's
// CompressionModel: what a line's writeback and fill move for each state of
// its tile, the metadata cache's traffic, and Hi-Z's bound.
#include <gtest/gtest.h>

#include <map>
#include <string>
#include <utility>
#include <vector>

#include "rtl_models/algo/compression.h"
#include "rtl_models/memory/tag_compression.h"

using namespace ropsim;

namespace {

constexpr uint32_t kLine = 64;
constexpr uint64_t kReadLatency = 100;  // the fake DRAM's read latency

/// Tiles whose contents the test sets.
class FakeTiles : public TileSource {
 public:
  std::map<std::pair<int, uint64_t>, TileInfo> info;
  int asked = 0;
  TileInfo tile(Buffer b, uint64_t tile, bool, const TilePatch*, size_t) override {
    ++asked;
    const auto it = info.find({int(b), tile});
    return it == info.end() ? TileInfo{true, 0, 1.0f} : it->second;
  }
};

/// A DRAM that records every burst.
class RecordingDram : public BurstSink {
 public:
  struct Burst {
    uint64_t addr;
    uint32_t bytes;
    bool write;
    Buffer b;
    uint64_t after;  // requested this many cycles after the current request cycle
  };
  std::vector<Burst> bursts;
  uint64_t access(uint64_t addr, uint32_t bytes, bool write, Buffer b, uint64_t after) override {
    bursts.push_back(Burst{addr, bytes, write, b, after});
    return write ? 0 : after + kReadLatency;
  }
  /// Bytes of the bursts to addresses below the metadata half (the data).
  uint64_t data_bytes(bool write) const {
    uint64_t n = 0;
    for (const Burst& x : bursts)
      if (x.write == write && !((x.addr >> 47) & 1u)) n += x.bytes;
    return n;
  }
  uint64_t metadata_bytes(bool write) const {
    uint64_t n = 0;
    for (const Burst& x : bursts)
      if (x.write == write && ((x.addr >> 47) & 1u)) n += x.bytes;
    return n;
  }
};

HwConfig design(uint32_t metadata_cache_bytes = 16384) {
  HwConfig hw;
  hw.cache.line_bytes = kLine;
  hw.compression.depth = hw.compression.color = true;
  hw.compression.tile_pixels = 16;
  hw.compression.size_classes = 3;
  hw.compression.metadata_cache_bytes = metadata_cache_bytes;
  hw.compression.decompress_latency_cycles = 8;
  hw.distributor.rop_units = 2;
  hw.hiz.enable = true;
  return hw;
}

// 128 x 128 pixels at 4 spp: depth 4 B and colour 6 B a sample, so a depth
// memory tile (16 pixels) is 256 B = 4 lines; 1024 tiles a surface.
std::array<uint32_t, kBuffers> surfaces() {
  std::array<uint32_t, kBuffers> bps{};
  bps[size_t(Buffer::kDepth)] = 4;
  bps[size_t(Buffer::kColor)] = 6;
  return bps;
}
constexpr uint32_t kSize = 128;
constexpr int kSpp = 4;
uint64_t depth_line(uint64_t tile, uint64_t k = 0) { return tile * 256 + k * kLine; }

}  // namespace

// One row per state of a depth tile at its writeback: the data bytes the
// writeback moves, and what a later fill of the line reads and waits.
TEST(ApproxCompression, WritebackAndFillMoveTheTilesCompressedShare) {
  struct Row {
    const char* what;
    TileInfo tile;
    bool written;            // write_back's result: data went to DRAM
    uint64_t bytes_written;  // data bytes of the writeback
    uint64_t bytes_read;     // data bytes of the fill
    uint64_t fill_latency;   // the fill's latency (the metadata line is cached by then)
  };
  const Row rows[] = {
      {"a cleared tile moves nothing either way", {true, 0, 1.0f}, false, 0, 0, 0},
      {"a class-0 tile moves whole lines", {false, 0, 0.5f}, true, kLine, kLine, kReadLatency},
      {"a class-1 tile moves half lines, decompressed on a fill",
       {false, 1, 0.5f},
       true,
       kLine / 2,
       kLine / 2,
       kReadLatency + 8},
      {"a class-2 tile moves quarter lines, decompressed on a fill",
       {false, 2, 0.5f},
       true,
       kLine / 4,
       kLine / 4,
       kReadLatency + 8},
  };
  for (const Row& r : rows) {
    FakeTiles tiles;
    tiles.info[{int(Buffer::kDepth), 5}] = r.tile;
    RecordingDram dram;
    TagOnlyCompression c(design(), kSize, kSize, kSpp, surfaces(), 1.0f, tiles);
    c.set_dram(&dram);
    EXPECT_EQ(c.write_back(depth_line(5, 1), Buffer::kDepth, 0), r.written) << r.what;
    EXPECT_EQ(dram.data_bytes(true), r.bytes_written) << r.what << ": data bytes of the writeback";
    EXPECT_EQ(c.stats().bytes_written[size_t(Buffer::kDepth)], r.bytes_written) << r.what;
    EXPECT_EQ(c.stats().bytes_written_uncompressed[size_t(Buffer::kDepth)], kLine) << r.what;
    EXPECT_EQ(dram.metadata_bytes(false), kLine) << r.what << ": the state bits' line is read once (a miss)";
    const uint64_t latency = c.fill(depth_line(5, 2), Buffer::kDepth, 0);
    EXPECT_EQ(dram.data_bytes(false), r.bytes_read) << r.what << ": data bytes of the fill";
    EXPECT_EQ(latency, r.fill_latency) << r.what << ": the fill's latency";
    EXPECT_EQ(c.stats().metadata_hits, 1u) << r.what << ": the fill finds the state bits cached";
  }
}

// A line of a tile never written back is stored uncompressed: a fill reads
// the whole line, after the state bits' line (a miss: both latencies).
TEST(ApproxCompression, ATileNeverWrittenBackIsReadWhole) {
  FakeTiles tiles;
  RecordingDram dram;
  TagOnlyCompression c(design(), kSize, kSize, kSpp, surfaces(), 1.0f, tiles);
  c.set_dram(&dram);
  EXPECT_EQ(c.fill(depth_line(7), Buffer::kDepth, 1), 2 * kReadLatency)
      << "a metadata miss then the data: the latencies add";
  EXPECT_EQ(dram.data_bytes(false), kLine);
  EXPECT_EQ(c.stats().lines_read[size_t(Buffer::kDepth)], 1u);
  EXPECT_EQ(tiles.asked, 0) << "a fill does not compress the tile";
}

// The data's size is in the tile's state bits: after a metadata miss, a
// fill requests its data burst when the state bits arrive (as the cycle
// model's CompressionModel::fill does), not beside the metadata read, so the
// channel serves the bursts requested after it behind it; with the state
// bits cached, at once.
TEST(ApproxCompression, AFillRequestsItsDataWhenTheStateBitsArrive) {
  FakeTiles tiles;
  RecordingDram dram;
  TagOnlyCompression c(design(), kSize, kSize, kSpp, surfaces(), 1.0f, tiles);
  c.set_dram(&dram);
  EXPECT_EQ(c.fill(depth_line(7), Buffer::kDepth, 0), 2 * kReadLatency);
  ASSERT_EQ(dram.bursts.size(), 2u) << "the state bits' line, then the data";
  EXPECT_TRUE((dram.bursts[0].addr >> 47) & 1u) << "the metadata read first";
  EXPECT_EQ(dram.bursts[0].after, 0u) << "the metadata read is requested with the fill";
  EXPECT_EQ(dram.bursts[1].after, kReadLatency) << "the data burst waits for the state bits";
  EXPECT_EQ(c.fill(depth_line(8), Buffer::kDepth, 0), kReadLatency) << "the same metadata line, cached";
  ASSERT_EQ(dram.bursts.size(), 3u);
  EXPECT_EQ(dram.bursts[2].after, 0u) << "state bits cached: the data burst at once";
}

// The metadata cache: a miss reads a line; evicting a dirty line writes it
// back; the flush writes the dirty lines; the traffic is its surface's.
TEST(ApproxCompression, MetadataMissesReadALineAndDirtyEvictionsWriteOne) {
  FakeTiles tiles;
  tiles.info[{int(Buffer::kColor), 0}] = TileInfo{false, 1, 1.0f};
  tiles.info[{int(Buffer::kColor), 600}] = TileInfo{false, 2, 1.0f};
  RecordingDram dram;
  // One metadata line per ROP; 2 state bits a tile: 256 tiles a line, so
  // tiles 0 and 600 have different lines.
  TagOnlyCompression c(design(kLine), kSize, kSize, kSpp, surfaces(), 1.0f, tiles);
  c.set_dram(&dram);
  const uint64_t color = uint64_t(Buffer::kColor) << 48, tile_bytes = 16 * kSpp * 6;
  c.write_back(color + 0 * tile_bytes, Buffer::kColor, 0);
  EXPECT_EQ(dram.metadata_bytes(true), 0u) << "nothing evicted yet";
  c.write_back(color + 600 * tile_bytes, Buffer::kColor, 0);
  EXPECT_EQ(dram.metadata_bytes(true), kLine) << "tile 600's state bits evict tile 0's dirty line";
  EXPECT_EQ(dram.metadata_bytes(false), 2 * kLine) << "two misses, two lines read";
  c.write_back(color + 0 * tile_bytes, Buffer::kColor, 1);
  EXPECT_EQ(dram.metadata_bytes(false), 3 * kLine) << "the other ROP has its own metadata cache";
  c.flush();
  EXPECT_EQ(dram.metadata_bytes(true), 3 * kLine) << "the flush writes both ROPs' dirty lines";
  c.flush();
  EXPECT_EQ(dram.metadata_bytes(true), 3 * kLine) << "a second flush has nothing dirty";
  for (const auto& x : dram.bursts) EXPECT_EQ(x.b, Buffer::kColor) << "metadata traffic is its surface's";
  EXPECT_EQ(c.stats().metadata_bytes_read[size_t(Buffer::kColor)], 3 * kLine);
  EXPECT_EQ(c.stats().metadata_bytes_written[size_t(Buffer::kColor)], 3 * kLine);
  EXPECT_EQ(dram.data_bytes(true), kLine / 2 + kLine / 4 + kLine / 2) << "classes 1, 2, 1";
}

// A tile's size is memoised until a write touches it.
TEST(ApproxCompression, ATouchedTileIsCompressedAgain) {
  FakeTiles tiles;
  tiles.info[{int(Buffer::kDepth), 3}] = TileInfo{false, 2, 0.5f};
  RecordingDram dram;
  TagOnlyCompression c(design(), kSize, kSize, kSpp, surfaces(), 1.0f, tiles);
  c.set_dram(&dram);
  c.write_back(depth_line(3, 0), Buffer::kDepth, 0);
  tiles.info[{int(Buffer::kDepth), 3}] = TileInfo{false, 0, 0.5f};
  c.write_back(depth_line(3, 1), Buffer::kDepth, 0);
  EXPECT_EQ(dram.data_bytes(true), 2 * kLine / 4) << "untouched: the memoised class 2";
  c.touched(depth_line(3, 2), Buffer::kDepth);
  c.write_back(depth_line(3, 2), Buffer::kDepth, 0);
  EXPECT_EQ(dram.data_bytes(true), 2 * kLine / 4 + kLine) << "touched: compressed again, now class 0";
  EXPECT_EQ(c.stats().writes_per_class[size_t(Buffer::kDepth)][2], 2u);
  EXPECT_EQ(c.stats().writes_per_class[size_t(Buffer::kDepth)][0], 1u);
}

// Hi-Z: the bound starts at the clear depth and becomes the tile's
// farthest depth at a writeback of one of its depth lines; a fragment is
// rejected when its nearest tested depth lies beyond it, in its own tile.
TEST(ApproxCompression, HizTakesTheFarthestDepthAtAWriteback) {
  FakeTiles tiles;
  // Tile 1 of the 8 x 8 tile at the origin: pixels rows 2 and 3 (16 pixels, rows of 8).
  tiles.info[{int(Buffer::kDepth), 1}] = TileInfo{false, 0, 0.25f};
  RecordingDram dram;
  TagOnlyCompression c(design(), kSize, kSize, kSpp, surfaces(), 1.0f, tiles);
  c.set_dram(&dram);
  EXPECT_FALSE(c.hiz_rejects(3, 2, 0.9f)) << "before any writeback the bound is the clear depth";
  c.write_back(depth_line(1), Buffer::kDepth, 0);
  EXPECT_FLOAT_EQ(c.hiz_bound(3, 2), 0.25f);
  EXPECT_TRUE(c.hiz_rejects(3, 2, 0.3f)) << "beyond the tile's farthest depth";
  EXPECT_TRUE(c.hiz_rejects(7, 3, 0.3f)) << "the tile's last pixel";
  EXPECT_FALSE(c.hiz_rejects(3, 2, 0.25f)) << "at the bound: may pass (LEQUAL)";
  EXPECT_FALSE(c.hiz_rejects(3, 1, 0.3f)) << "the tile above keeps the clear depth";
  EXPECT_FALSE(c.hiz_rejects(3, 4, 0.3f)) << "the tile below keeps the clear depth";
  EXPECT_EQ(c.stats().hiz_tests, 6u);
  EXPECT_EQ(c.stats().hiz_rejected, 2u);
  // Hi-Z alone (no depth compression): the bound from the tile's depths.
  HwConfig hw = design();
  hw.compression.depth = hw.compression.color = false;
  tiles.info[{int(Buffer::kDepth), 2}] = TileInfo{false, 0, 0.5f};
  TagOnlyCompression h(hw, kSize, kSize, kSpp, surfaces(), 1.0f, tiles);
  h.set_dram(&dram);
  EXPECT_FALSE(h.compresses(Buffer::kDepth));
  h.depth_written_back(depth_line(2));
  EXPECT_FLOAT_EQ(h.hiz_bound(0, 4), 0.5f) << "tile 2: rows 4 and 5";
}

// A memory tile's lines (the block its eviction writes together).
TEST(ApproxCompression, TileLinesAreTheTilesBlock) {
  FakeTiles tiles;
  TagOnlyCompression c(design(), kSize, kSize, kSpp, surfaces(), 1.0f, tiles);
  uint64_t first = 0, count = 0;
  c.tile_lines(depth_line(9, 3), Buffer::kDepth, first, count);
  EXPECT_EQ(first, depth_line(9));
  EXPECT_EQ(count, 4u) << "256 B of depth a tile, 64 B lines";
  const uint64_t color = uint64_t(Buffer::kColor) << 48;
  c.tile_lines(color + 384 + 10, Buffer::kColor, first, count);  // tile 1 of 384 B: bytes 384..767
  EXPECT_EQ(first, color + 384);
  EXPECT_EQ(count, 6u) << "384 B starting on a line boundary";
}
