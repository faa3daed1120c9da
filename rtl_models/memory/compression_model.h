// The timing side of surface compression (compression.h): what a ROP cache's
// DRAM traffic costs when its surfaces are stored compressed, and the
// metadata cache of each ROP holding the tiles' state bits.
//   - A dirty line of a compressed surface written to DRAM moves its share of
//     its memory tile's block: line_bytes >> class, the class being that of
//     the tile's contents at the writeback (TileSource), after
//     compress_latency_cycles; a tile holding only the clear value moves
//     nothing (its state bits say cleared). The state bits are written
//     through the ROP's metadata cache.
//   - A fill of such a line reads the tile's state bits (the metadata cache;
//     a miss reads a metadata line first), then line_bytes >> class of the
//     class stored at the tile's last writeback, plus
//     decompress_latency_cycles when it was compressed.
//   - Hierarchical Z: per depth memory tile the farthest stored depth,
//     updated when the tile is written back (the compressor sees the whole
//     tile then). Stored depths only move nearer (a write passes
//     LESS_EQUAL), so an older bound is never nearer than the tile's current
//     farthest depth: rejecting a fragment whose tested samples all lie
//     beyond it never rejects one that would pass.
// Metadata traffic is DRAM traffic of the surface it describes.
// The compressor sees a tile as the caches do: the functional store less the
// functional writes whose posted cache writes have not been applied yet
// (PostedWrites). A unit records what each posted write replaced (pend); the
// cache marks it applied. So a tile's contents at a writeback depend only on
// the order of the applied writes, (cycle, ROP, post order), and a decoupled
// run, whose writeback units run ahead of SystemC time, compresses every
// tile exactly as a lockstep run does.
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "rtl_models/algo/buffers.h"
#include "rtl_models/algo/compression.h"
#include "rtl_models/config/hw_config.h"
#include "rtl_models/memory/cache_tags.h"
#include "rtl_models/memory/dram.h"
#include "util/containers/paged_array.h"
#include "util/containers/ring_queue.h"

namespace ropsim {

/// A memory tile's contents as the compressor sees them (the cycle model
/// implements it over the functional store).
struct TileInfo {
  bool cleared = false;    ///< only the clear value
  int size_class = 0;      ///< block U >> size_class (0: uncompressed)
  float max_depth = 1.0f;  ///< depth: its farthest stored depth
};
class TileSource {
 public:
  virtual ~TileSource() = default;
  /// Tile `tile` (address-map pixel index / tile_pixels) of surface b now,
  /// with the n patches written over its bytes in order (each restores what
  /// a pending write replaced; newest first); without `size` only `cleared`
  /// and `max_depth` (no compression).
  virtual TileInfo tile(Buffer b, uint64_t tile, bool size, const TilePatch* undo, size_t n) = 0;
};

struct CompressionTraffic {
  /// Line transfers of the compressed surfaces, and their bytes had they been
  /// uncompressed (line_bytes each) and as moved.
  std::array<uint64_t, kBuffers> lines_written{}, lines_read{};
  std::array<uint64_t, kBuffers> bytes_written_uncompressed{}, bytes_written{}, bytes_read_uncompressed{}, bytes_read{};
  /// Line writebacks by the block size of their tile: [b][j], U >> j;
  /// cleared tiles (no bytes) apart.
  std::array<std::array<uint64_t, 4>, kBuffers> writes_per_class{};
  std::array<uint64_t, kBuffers> writes_cleared{};
  std::array<uint64_t, kBuffers> metadata_bytes_read{}, metadata_bytes_written{};
  uint64_t metadata_hits = 0, metadata_misses = 0;
  uint64_t hiz_tests = 0, hiz_rejected = 0;
  uint64_t hiz_lines_skipped = 0;  ///< depth lines the rejected fragments did not read
  CompressionTraffic& operator+=(const CompressionTraffic& o);
  CompressionTraffic& operator-=(const CompressionTraffic& o);

  /// Calls f(x, y) for every count x of a and its like y of b, in one fixed
  /// order: the one list of the counts (sums, differences, a worker's
  /// message).
  template <class A, class B, class F>
  static void for_each_count(A& a, B& b, F&& f) {
    for (size_t i = 0; i < size_t(kBuffers); ++i) {
      f(a.lines_written[i], b.lines_written[i]);
      f(a.lines_read[i], b.lines_read[i]);
      f(a.bytes_written_uncompressed[i], b.bytes_written_uncompressed[i]);
      f(a.bytes_written[i], b.bytes_written[i]);
      f(a.bytes_read_uncompressed[i], b.bytes_read_uncompressed[i]);
      f(a.bytes_read[i], b.bytes_read[i]);
      for (size_t j = 0; j < 4; ++j) f(a.writes_per_class[i][j], b.writes_per_class[i][j]);
      f(a.writes_cleared[i], b.writes_cleared[i]);
      f(a.metadata_bytes_read[i], b.metadata_bytes_read[i]);
      f(a.metadata_bytes_written[i], b.metadata_bytes_written[i]);
    }
    f(a.metadata_hits, b.metadata_hits);
    f(a.metadata_misses, b.metadata_misses);
    f(a.hiz_tests, b.hiz_tests);
    f(a.hiz_rejected, b.hiz_rejected);
    f(a.hiz_lines_skipped, b.hiz_lines_skipped);
  }
};

class CompressionModel {
 public:
  /// tiles_x: 8 x 8 tiles per screen row; bytes_per_sample[b] of each surface.
  CompressionModel(const HwConfig& hw, uint32_t width, uint32_t height, int spp,
                   const std::array<uint32_t, kBuffers>& bytes_per_sample, float clear_depth, uint32_t rops);
  void set_source(TileSource* src) { src_ = src; }
  /// The DRAM of the current pass.
  void set_dram(Dram* d) { dram_ = d; }
  bool compresses(Buffer b) const { return on_[size_t(b)]; }
  /// A dirty line of a compressed surface leaves ROP `rop`'s cache at cycle
  /// now: writes its bytes to DRAM (and the state bits to the metadata
  /// cache); returns false when the tile was cleared (nothing written).
  bool write_back(uint64_t line, Buffer b, uint64_t now, uint32_t rop, uint64_t& done);
  /// A dirty depth line of an uncompressed depth surface leaves a cache:
  /// Hi-Z takes its tile's farthest depth.
  void depth_written_back(uint64_t line) {
    if (hiz_)
      zmax_[tile_of(line, Buffer::kDepth)] = view(Buffer::kDepth, tile_of(line, Buffer::kDepth), false).max_depth;
  }
  /// Surface b's tiles are compressed, or (depth) bound by Hi-Z: a unit's
  /// functional write to it is recorded with pend.
  bool tracks(Buffer b) const { return on_[size_t(b)] || (hiz_ && b == Buffer::kDepth); }
  static constexpr uint32_t kNoPatch = ~uint32_t{0};
  /// A write of `line` posted to a cache (not yet applied), whose functional
  /// write replaced the pixel's bytes [pixel_addr, pixel_addr + pixel_bytes)
  /// (addresses of the address map) that were `old`, and for depth the
  /// samples' plane keys `old_planes` (nullptr: not kept): records the part
  /// in the line; returns its id for applied().
  uint32_t pend(uint64_t line, Buffer b, uint64_t pixel_addr, uint32_t pixel_bytes, const uint8_t* old,
                const uint64_t* old_planes = nullptr);
  /// The cache applied the posted write `id` (its bytes are now the cache's).
  void applied(uint32_t id);
  /// The first line and the number of lines of the tile holding line.
  void tile_lines(uint64_t line, Buffer b, uint64_t& first, uint64_t& count) const {
    const uint64_t base = uint64_t(b) << 48, tb = tile_bytes_[size_t(b)];
    const uint64_t start = base + tile_of(line, b) * tb;
    first = start & line_mask_;
    count = ((start + tb - 1) >> line_shift_) - (first >> line_shift_) + 1;
  }
  /// A fill of a line in DRAM: returns the cycle its (decompressed) data is there.
  uint64_t fill(uint64_t line, Buffer b, uint64_t now, uint32_t rop);
  /// The tile's stored state was cleared at its last writeback: a fill is a clear fill.
  bool stored_cleared(uint64_t line, Buffer b) const;
  /// A write to the line (its tile's contents changed).
  void touched(uint64_t line, Buffer b) { memo_valid_[size_t(b)][tile_of(line, b)] = 0; }
  /// Writes the metadata caches' dirty lines back at cycle now; returns the last completion.
  uint64_t flush(uint64_t now);
  /// Hi-Z: would the fragment at pixel (x, y) whose tested samples' nearest
  /// depth is zmin fail every sample? (Counts the test.)
  bool hiz_rejects(uint32_t x, uint32_t y, float zmin);
  void count_skipped(uint64_t lines) { s_.hiz_lines_skipped += lines; }
  bool hiz() const { return hiz_; }
  const CompressionTraffic& stats() const { return s_; }

  // Sampled warming (livepoints.h): the state a full run would hold at a
  // live-point, set before its unit runs, without time, DRAM traffic or
  // statistics.
  /// Memory tiles of surface b (0 when b is neither compressed nor Hi-Z bound).
  uint64_t tile_count(Buffer b) const { return stored_[size_t(b)].size(); }
  /// Tile `tile` of surface b taken as written back with its current
  /// contents: its state bits (cleared or its class) and, for depth, Hi-Z's
  /// bound. A tile holding only the clear value stays never written. Returns
  /// its contents' TileInfo.
  TileInfo warm_tile(Buffer b, uint64_t tile);
  /// The metadata line holding the state bits of line's tile (surface b compressed).
  uint64_t metadata_line(uint64_t line, Buffer b) const {
    const uint64_t addr = (uint64_t(b) << 48 | uint64_t{1} << 47) + tile_of(line, b) * uint64_t(meta_bits_) / 8;
    return addr & line_mask_;
  }
  /// A tag-only access to the state bits of line's tile through ROP rop's
  /// metadata cache (a fill reads them, a write-back writes them).
  void warm_metadata(uint64_t line, Buffer b, bool write, uint32_t rop);
  /// The state a live-point's warming sets, for comparing two warmings
  /// (the library's round trip): per surface and tile the stored state bits,
  /// Hi-Z's bounds, and per ROP the metadata cache's tags and dirty bits.
  struct WarmState {
    std::array<std::vector<uint8_t>, kBuffers> stored;
    std::vector<float> zmax;
    std::vector<std::vector<uint64_t>> meta_tags;
    std::vector<std::vector<uint8_t>> meta_dirty;
    bool operator==(const WarmState& o) const {
      return stored == o.stored && zmax == o.zmax && meta_tags == o.meta_tags && meta_dirty == o.meta_dirty;
    }
  };
  WarmState warm_state() const;

  /// Host bytes (memory_estimate.h): one ROP's metadata cache of hw (tags,
  /// LRU, dirty bit, ready cycle and draw per line); the memory tiles of a
  /// width x height screen (each surface's per-tile state is paged, charged
  /// as the frame touches it).
  static uint64_t metadata_cache_bytes(const HwConfig& hw);
  static uint64_t screen_tiles(const HwConfig& hw, uint32_t width, uint32_t height);

 private:
  uint64_t tile_of(uint64_t line, Buffer b) const { return tile_div_[size_t(b)].div(line - (uint64_t(b) << 48)); }
  TileInfo info(Buffer b, uint64_t tile);
  /// The tile as the caches see it (the store less the pending writes).
  TileInfo view(Buffer b, uint64_t tile, bool size);
  /// The state bits' line of a tile through ROP rop's metadata cache; returns when they are there.
  uint64_t metadata(Buffer b, uint64_t tile, bool write, uint64_t now, uint32_t rop);

  HwConfig::Compression cfg_;
  CompressionFormat fmt_;
  uint32_t line_bytes_;  // a power of two (hw_config.cpp):
  uint64_t line_mask_;   // an address's line: addr & line_mask_
  int line_shift_;
  std::array<bool, kBuffers> on_{};
  std::array<uint64_t, kBuffers> tile_bytes_{};
  std::array<Divisor, kBuffers> tile_div_;  // by tile_bytes_
  int meta_bits_;
  TileSource* src_ = nullptr;
  Dram* dram_ = nullptr;
  // Per surface and memory tile (paged: the pages of the tiles a frame touches):
  static constexpr const char* kTileState = "the compression model's per-tile state";
  std::array<PagedArray<TileInfo>, kBuffers> memo_;       // its contents compressed since its last write,
  std::array<PagedArray<uint8_t>, kBuffers> memo_valid_;  // when 1
  std::array<PagedArray<uint8_t>, kBuffers> stored_;      // state bits in memory: 0 cleared, 1 + class, kNever
  static constexpr uint8_t kNever = 0xFF;                 // never written back (stored uncompressed)
  // Pending writes, in post order: record id - first_id_ (modulo kNoPatch)
  // indexes pending_; their replaced bytes in the ring bytes_, in the same
  // order, from bytes_head_ to bytes_end_ (log_reserve). The ring grows,
  // never shrinks: it stays the size of the writes in flight, so the log
  // stays in the host's caches.
  struct Pending {  // 32 bytes
    uint64_t tile;
    size_t at;             // in bytes_: len replaced bytes, then the plane keys' bytes
    uint32_t offset, len;  // in the memory tile
    uint32_t plane_len;    // bytes of replaced plane keys (0: none)
    uint8_t buf;           // its Buffer
    bool applied;
  };
  static_assert(sizeof(Pending) == 32, "a pending write indexes by a shift");
  RingQueue<Pending> pending_;
  uint32_t first_id_ = 0;
  std::vector<uint8_t> bytes_;
  size_t bytes_head_ = 0, bytes_end_ = 0;
  bool wrapped_ = false;  // the live bytes wrap past the ring's top
  /// Room for n bytes at the log's end; returns their offset in bytes_. The
  /// live bytes run from bytes_head_ to bytes_end_, or when wrapped_ from
  /// bytes_head_ to the ring's top and from 0 to bytes_end_.
  size_t log_reserve(size_t n) {
    if (bytes_end_ + n > (wrapped_ ? bytes_head_ : bytes_.size())) return log_reserve_past_top(n);
    const size_t at = bytes_end_;
    bytes_end_ += n;
    return at;
  }
  /// log_reserve when the bytes do not fit at the end: at the ring's bottom,
  /// or the ring grows.
  size_t log_reserve_past_top(size_t n);
  std::array<PagedArray<uint32_t>, kBuffers> pending_count_;  // per tile, not yet applied
  std::vector<TilePatch> patches_;                            // view's scratch
  struct MetaCache {
    CacheTags tags;
    std::vector<uint8_t> dirty;
    std::vector<uint64_t> ready;
    std::vector<uint32_t> draw;  // the draw that wrote the line last (attribution.h)
    // The line of the last access and its way: a tile's lines leave as a
    // block, each touching the same state bits. Found again, it is already
    // its set's most recent, so its use needs no new tick.
    uint64_t last_line = CacheTags::kInvalid;
    size_t last_way = 0;
  };
  std::vector<MetaCache> meta_;  // per ROP
  bool hiz_;
  uint32_t tiles_x_;
  PagedArray<float> zmax_;  // per depth memory tile
  CompressionTraffic s_;
};

}  // namespace ropsim
