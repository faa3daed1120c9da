#include "rtl_models/memory/tag_compression.h"

#include <algorithm>

#include "rtl_models/algo/bits.h"

namespace ropsim {

namespace {
/// The metadata cache's shape: compression.metadata_cache_bytes (at least
/// a line) of cache.line_bytes lines, up to 8 ways (as compression_model.cpp).
HwConfig::Cache metadata_cache_shape(const HwConfig& hw) {
  HwConfig::Cache c = hw.cache;
  c.size_bytes = std::max(hw.compression.metadata_cache_bytes, hw.cache.line_bytes);
  c.ways = std::min<uint32_t>(8, c.size_bytes / c.line_bytes);
  return c;
}
}  // namespace

TagOnlyCompression::TagOnlyCompression(const HwConfig& hw, uint32_t width, uint32_t height, int spp,
                                       const std::array<uint32_t, kBuffers>& bps, float clear_depth, TileSource& tiles)
    : cfg_(hw.compression),
      line_bytes_(hw.cache.line_bytes),
      tile_pixels_(hw.compression.tile_pixels),
      tiles_x_(ceil_div(width, 8u)),
      meta_bits_(metadata_bits(hw.compression.setup().format)),
      tiles_(tiles),
      hiz_(hw.hiz.enable) {
  on_[size_t(Buffer::kDepth)] = cfg_.depth && bps[size_t(Buffer::kDepth)];
  for (Buffer b : {Buffer::kColor, Buffer::kTransmittance, Buffer::kAccum})
    on_[size_t(b)] = cfg_.color && bps[size_t(b)];
  for (size_t b = 0; b < size_t(kBuffers); ++b)
    tile_bytes_[b] = std::max<uint64_t>(1, uint64_t(tile_pixels_) * uint64_t(spp) * bps[b]);
  const size_t screen_tiles = size_t(tiles_x_) * ceil_div(height, 8u) * (64u / tile_pixels_);
  for (size_t b = 0; b < size_t(kBuffers); ++b) {
    if (!on_[b]) continue;
    memo_[b].assign(screen_tiles, TileInfo{}, kTileState);
    memo_valid_[b].assign(screen_tiles, 0, kTileState);
    stored_[b].assign(screen_tiles, kNever, kTileState);
  }
  if (cfg_.depth || cfg_.color) {
    const HwConfig::Cache shape = metadata_cache_shape(hw);
    for (uint32_t r = 0; r < hw.distributor.rop_units; ++r) {
      MetaCache m{CacheTags(shape), {}};
      m.dirty.assign(m.tags.size(), 0);
      meta_.push_back(std::move(m));
    }
  }
  if (hiz_) zmax_.assign(screen_tiles, clear_depth, "Hi-Z's per-tile bounds");
}

TileInfo TagOnlyCompression::info(Buffer b, uint64_t tile) {
  if (memo_valid_[size_t(b)][tile]) return memo_[size_t(b)][tile];
  const TileInfo t = tiles_.tile(b, tile, true, nullptr, 0);
  memo_[size_t(b)][tile] = t;
  memo_valid_[size_t(b)][tile] = 1;
  return t;
}

void TagOnlyCompression::tile_lines(uint64_t line, Buffer b, uint64_t& first, uint64_t& count) const {
  const uint64_t tb = tile_bytes_[size_t(b)];
  const uint64_t start = (uint64_t(b) << 48) + tile_of(line, b) * tb;
  first = start / line_bytes_ * line_bytes_;
  count = (start + tb - 1) / line_bytes_ - first / line_bytes_ + 1;
}

uint64_t TagOnlyCompression::metadata(Buffer b, uint64_t tile, bool write, uint32_t rop) {
  MetaCache& m = meta_[rop];
  // The state bits of the surface's tiles, packed, in the upper half of its
  // address space (as compression_model.cpp).
  const uint64_t addr = (uint64_t(b) << 48 | uint64_t{1} << 47) + tile * uint64_t(meta_bits_) / 8;
  const uint64_t line = addr / line_bytes_ * line_bytes_;
  bool hit = false;
  const size_t way = m.tags.find(line, hit);
  uint64_t latency = 0;
  if (hit) {
    ++s_.metadata_hits;
  } else {
    ++s_.metadata_misses;
    const uint64_t old = m.tags.tag(way);
    if (old != CacheTags::kInvalid && m.dirty[way]) {
      const Buffer ob = Buffer((old >> 48) & 7u);
      dram_->access(old, line_bytes_, true, ob, 0);
      s_.metadata_bytes_written[size_t(ob)] += line_bytes_;
    }
    m.tags.install(way, line);
    m.dirty[way] = 0;
    latency = dram_->access(line, line_bytes_, false, b, 0);
    s_.metadata_bytes_read[size_t(b)] += line_bytes_;
  }
  if (write) m.dirty[way] = 1;
  return latency;
}

bool TagOnlyCompression::write_back(uint64_t line, Buffer b, uint32_t rop) {
  const uint64_t tile = tile_of(line, b);
  const TileInfo t = info(b, tile);
  if (b == Buffer::kDepth && hiz_) zmax_[tile] = t.max_depth;
  metadata(b, tile, true, rop);  // posted: the data write does not wait for it
  ++s_.lines_written[size_t(b)];
  s_.bytes_written_uncompressed[size_t(b)] += line_bytes_;
  if (t.cleared) {
    stored_[size_t(b)][tile] = 0;
    ++s_.writes_cleared[size_t(b)];
    return false;
  }
  stored_[size_t(b)][tile] = uint8_t(1 + t.size_class);
  ++s_.writes_per_class[size_t(b)][size_t(t.size_class)];
  const uint32_t bytes = std::max<uint32_t>(1, line_bytes_ >> t.size_class);
  s_.bytes_written[size_t(b)] += bytes;
  dram_->access(line, bytes, true, b, 0);
  return true;
}

void TagOnlyCompression::depth_written_back(uint64_t line) {
  if (!hiz_) return;
  const uint64_t tile = tile_of(line, Buffer::kDepth);
  zmax_[tile] = tiles_.tile(Buffer::kDepth, tile, false, nullptr, 0).max_depth;
}

uint64_t TagOnlyCompression::fill(uint64_t line, Buffer b, uint32_t rop) {
  const uint64_t tile = tile_of(line, b);
  const uint64_t meta = metadata(b, tile, false, rop);
  const uint8_t st = stored_[size_t(b)][tile];
  if (st == 0) return meta;  // cleared: the clear value, no data read
  const int c = st == kNever ? 0 : st - 1;
  const uint32_t bytes = std::max<uint32_t>(1, line_bytes_ >> c);
  ++s_.lines_read[size_t(b)];
  s_.bytes_read_uncompressed[size_t(b)] += line_bytes_;
  s_.bytes_read[size_t(b)] += bytes;
  // How many bytes to read is in the state bits: the data burst is requested
  // when they are there (meta cycles later after a miss, as
  // CompressionModel::fill requests it), and the channel serves the bursts
  // requested after it behind it.
  return dram_->access(line, bytes, false, b, meta) + (c ? cfg_.decompress_latency_cycles : 0);
}

void TagOnlyCompression::flush() {
  for (MetaCache& m : meta_)
    for (size_t w = 0; w < m.dirty.size(); ++w)
      if (m.dirty[w] && m.tags.tag(w) != CacheTags::kInvalid) {
        const Buffer b = Buffer((m.tags.tag(w) >> 48) & 7u);
        dram_->access(m.tags.tag(w), line_bytes_, true, b, 0);
        s_.metadata_bytes_written[size_t(b)] += line_bytes_;
        m.dirty[w] = 0;
      }
}

bool TagOnlyCompression::hiz_rejects(uint32_t x, uint32_t y, float zmin) {
  ++s_.hiz_tests;
  const bool reject = zmin > zmax_[pixel_tile(x, y)];
  s_.hiz_rejected += reject;
  return reject;
}

}  // namespace ropsim
