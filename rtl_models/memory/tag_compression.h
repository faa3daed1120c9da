// Surface compression and hierarchical Z in the analytical model
// (--fidelity approximate): the rules of the cycle model's CompressionModel
// (compression_model.h), tag-only and without time.
//   - A dirty line of a compressed surface written back moves line_bytes >>
//     class of its memory tile's contents at the writeback (TileSource: the
//     functional store as it is then); a tile holding only the clear value
//     moves nothing. The tile's state bits are written through the ROP's
//     metadata cache.
//   - A fill of such a line looks the tile's state bits up in the metadata
//     cache (a miss reads a metadata line, after writing back the dirty line
//     it evicts), then reads line_bytes >> the class stored at the tile's
//     last writeback (a tile never written back: line_bytes; a cleared one:
//     nothing); its latency adds the metadata read's and, for a compressed
//     tile, decompress_latency_cycles.
//   - Hi-Z: per depth memory tile the farthest stored depth, taken at each
//     writeback of a depth line; a fragment whose tested samples' nearest
//     depth lies beyond it is rejected before its lines are read.
// Metadata traffic is DRAM traffic of the surface it describes. The
// compress latency delays posted writes only; the analytical model charges
// it to the final flush (approximate.cpp).
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "rtl_models/algo/buffers.h"
#include "rtl_models/config/hw_config.h"
#include "rtl_models/memory/cache_tags.h"
#include "rtl_models/memory/compression_model.h"
#include "util/containers/paged_array.h"

namespace ropsim {

/// Where the tag-only model's bursts go (the analytical model's DRAM).
class BurstSink {
 public:
  virtual ~BurstSink() = default;
  /// One burst of `bytes` at addr of surface b, requested `after` cycles
  /// after the current request cycle (a burst that must wait for an earlier
  /// one's data); returns a read's latency in cycles from the current
  /// request cycle, `after` included (0 for a write).
  virtual uint64_t access(uint64_t addr, uint32_t bytes, bool write, Buffer b, uint64_t after) = 0;
};

class TagOnlyCompression {
 public:
  /// bytes_per_sample[b] of each surface the run uses (0: unused);
  /// clear_depth: the depth surface's clear value (Hi-Z's first bound);
  /// tiles: the memory tiles' contents as they are when asked.
  TagOnlyCompression(const HwConfig& hw, uint32_t width, uint32_t height, int spp,
                     const std::array<uint32_t, kBuffers>& bytes_per_sample, float clear_depth, TileSource& tiles);
  /// The DRAM of the current pass (the state bits, stored classes and Hi-Z
  /// bounds outlive the passes, as the metadata caches do).
  void set_dram(BurstSink* d) { dram_ = d; }
  bool compresses(Buffer b) const { return on_[size_t(b)]; }
  bool hiz() const { return hiz_; }
  /// A dirty line of a compressed surface leaves ROP rop's cache: its
  /// compressed bytes to DRAM, its tile's state bits to the metadata cache.
  /// Returns false when the tile was cleared (no data written).
  bool write_back(uint64_t line, Buffer b, uint32_t rop);
  /// A dirty line of an uncompressed depth surface leaves a cache: Hi-Z
  /// takes its tile's farthest depth.
  void depth_written_back(uint64_t line);
  /// A fill of a line of a compressed surface DRAM holds, by ROP rop:
  /// returns the cycles until its data is there (before the cache's hit
  /// latency). The data's size is in the tile's state bits, so after a
  /// metadata miss its burst is requested when they arrive.
  uint64_t fill(uint64_t line, Buffer b, uint32_t rop);
  /// A write to the line (its tile's contents changed).
  void touched(uint64_t line, Buffer b) {
    if (on_[size_t(b)]) memo_valid_[size_t(b)][tile_of(line, b)] = 0;
  }
  /// The first line and the number of lines of the memory tile holding line.
  void tile_lines(uint64_t line, Buffer b, uint64_t& first, uint64_t& count) const;
  /// Writes the metadata caches' dirty lines back (the end of a pass).
  void flush();
  /// Hi-Z: would the fragment at pixel (x, y) whose tested samples' nearest
  /// depth is zmin fail every sample? (Counts the test.)
  bool hiz_rejects(uint32_t x, uint32_t y, float zmin);
  void count_skipped(uint64_t lines) { s_.hiz_lines_skipped += lines; }
  /// The farthest depth Hi-Z holds for the tile of pixel (x, y).
  float hiz_bound(uint32_t x, uint32_t y) const { return zmax_.get(pixel_tile(x, y)); }
  const CompressionTraffic& stats() const { return s_; }

 private:
  uint64_t tile_of(uint64_t line, Buffer b) const { return (line - (uint64_t(b) << 48)) / tile_bytes_[size_t(b)]; }
  uint64_t pixel_tile(uint32_t x, uint32_t y) const {
    return ((uint64_t(y >> 3) * tiles_x_ + (x >> 3)) * 64 + ((y & 7u) << 3 | (x & 7u))) / tile_pixels_;
  }
  /// The tile's contents compressed, memoised until it is written again.
  TileInfo info(Buffer b, uint64_t tile);
  /// The state bits' line of a tile through ROP rop's metadata cache;
  /// returns the cycles until they are there (0 on a hit).
  uint64_t metadata(Buffer b, uint64_t tile, bool write, uint32_t rop);

  HwConfig::Compression cfg_;
  uint32_t line_bytes_, tile_pixels_, tiles_x_;
  int meta_bits_;
  std::array<bool, kBuffers> on_{};
  std::array<uint64_t, kBuffers> tile_bytes_{};
  TileSource& tiles_;
  BurstSink* dram_ = nullptr;
  // Per surface and memory tile (paged: the pages of the tiles a frame touches).
  static constexpr const char* kTileState = "the approximate model's per-tile compression state";
  std::array<PagedArray<TileInfo>, kBuffers> memo_;
  std::array<PagedArray<uint8_t>, kBuffers> memo_valid_;
  std::array<PagedArray<uint8_t>, kBuffers> stored_;  // state bits in memory: 0 cleared, 1 + class, kNever
  static constexpr uint8_t kNever = 0xFF;             // never written back (stored uncompressed)
  struct MetaCache {
    CacheTags tags;
    std::vector<uint8_t> dirty;
  };
  std::vector<MetaCache> meta_;  // per ROP
  bool hiz_;
  PagedArray<float> zmax_;  // per depth memory tile
  CompressionTraffic s_;
};

}  // namespace ropsim
