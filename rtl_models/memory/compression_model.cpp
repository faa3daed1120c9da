#include "rtl_models/memory/compression_model.h"

#include <algorithm>
#include <cstring>

#include "rtl_models/algo/bits.h"
#include "rtl_models/algo/compression.h"

namespace ropsim {

CompressionTraffic& CompressionTraffic::operator+=(const CompressionTraffic& o) {
  for_each_count(*this, o, [](uint64_t& x, const uint64_t& y) { x += y; });
  return *this;
}

CompressionTraffic& CompressionTraffic::operator-=(const CompressionTraffic& o) {
  for_each_count(*this, o, [](uint64_t& x, const uint64_t& y) { x -= y; });
  return *this;
}

namespace {
HwConfig::Cache meta_cache_shape(const HwConfig& hw) {
  HwConfig::Cache c = hw.cache;
  c.size_bytes = std::max(hw.compression.metadata_cache_bytes, hw.cache.line_bytes);
  c.ways = std::min<uint32_t>(8, c.size_bytes / c.line_bytes);
  return c;
}
}  // namespace

uint64_t CompressionModel::metadata_cache_bytes(const HwConfig& hw) {
  const uint64_t lines = CacheTags::ways_of(meta_cache_shape(hw));
  return lines * (CacheTags::bytes_per_way() + sizeof(decltype(MetaCache::dirty)::value_type) +
                  sizeof(decltype(MetaCache::ready)::value_type) + sizeof(decltype(MetaCache::draw)::value_type));
}

uint64_t CompressionModel::screen_tiles(const HwConfig& hw, uint32_t width, uint32_t height) {
  return uint64_t(ceil_div(width, 8u)) * ceil_div(height, 8u) * (64u / hw.compression.tile_pixels);
}

CompressionModel::CompressionModel(const HwConfig& hw, uint32_t width, uint32_t height, int spp,
                                   const std::array<uint32_t, kBuffers>& bps, float clear_depth, uint32_t rops)
    : cfg_(hw.compression),
      fmt_(hw.compression.setup().format),
      line_bytes_(hw.cache.line_bytes),
      line_mask_(~(uint64_t{hw.cache.line_bytes} - 1)),
      line_shift_(log2_floor(uint64_t{hw.cache.line_bytes})),
      meta_bits_(metadata_bits(fmt_)),
      hiz_(hw.hiz.enable),
      tiles_x_(ceil_div(width, 8u)) {
  on_[size_t(Buffer::kDepth)] = cfg_.depth;
  for (Buffer b : {Buffer::kColor, Buffer::kTransmittance, Buffer::kAccum})
    on_[size_t(b)] = cfg_.color && bps[size_t(b)];
  for (size_t b = 0; b < size_t(kBuffers); ++b) {
    tile_bytes_[b] = std::max<uint64_t>(1, uint64_t(fmt_.tile_pixels) * uint64_t(spp) * bps[b]);
    tile_div_[b] = Divisor(tile_bytes_[b]);
  }
  const HwConfig::Cache shape = meta_cache_shape(hw);
  for (uint32_t r = 0; r < rops; ++r) {
    MetaCache m{CacheTags(shape), {}, {}, {}};
    m.dirty.assign(m.tags.size(), 0);
    m.ready.assign(m.tags.size(), 0);
    m.draw.assign(m.tags.size(), 0);
    meta_.push_back(std::move(m));
  }
  const size_t screen_tiles = size_t(tiles_x_) * ceil_div(height, 8u) * (64u / fmt_.tile_pixels);
  for (size_t b = 0; b < size_t(kBuffers); ++b) {
    if (!on_[b] && !(hiz_ && Buffer(b) == Buffer::kDepth)) continue;
    memo_[b].assign(screen_tiles, TileInfo{}, kTileState);
    memo_valid_[b].assign(screen_tiles, 0, kTileState);
    stored_[b].assign(screen_tiles, kNever, kTileState);
    pending_count_[b].assign(screen_tiles, 0, kTileState);
  }
  if (hiz_) zmax_.assign(screen_tiles, clear_depth, "Hi-Z's per-tile bounds");
}

TileInfo CompressionModel::info(Buffer b, uint64_t tile) {
  if (memo_valid_[size_t(b)][tile]) return memo_[size_t(b)][tile];
  const TileInfo t = view(b, tile, true);
  memo_[size_t(b)][tile] = t;
  memo_valid_[size_t(b)][tile] = 1;
  return t;
}

TileInfo CompressionModel::view(Buffer b, uint64_t tile, bool size) {
  patches_.clear();
  if (pending_count_[size_t(b)][tile])  // newest first
    for (size_t i = pending_.size(); i-- > 0;) {
      const Pending& p = pending_[i];
      if (!p.applied && Buffer(p.buf) == b && p.tile == tile)
        patches_.push_back(TilePatch{p.offset, p.len, &bytes_[p.at], p.plane_len ? &bytes_[p.at + p.len] : nullptr});
    }
  return src_->tile(b, tile, size, patches_.data(), patches_.size());
}

uint32_t CompressionModel::pend(uint64_t line, Buffer b, uint64_t pixel_addr, uint32_t pixel_bytes, const uint8_t* old,
                                const uint64_t* old_planes) {
  // The pixel's bytes in the line, and their tile (a pixel lies in one memory tile).
  const uint64_t lo = std::max(line, pixel_addr), hi = std::min(line + line_bytes_, pixel_addr + pixel_bytes);
  if (hi <= lo) return kNoPatch;
  const uint64_t tile = tile_of(pixel_addr, b);
  const uint64_t tile_start = (uint64_t(b) << 48) + tile * tile_bytes_[size_t(b)];
  // The replaced bytes, then (depth: kDepthSampleBytes a sample) the same samples' keys.
  const uint32_t len = uint32_t(hi - lo);
  const uint32_t plane_len = old_planes ? uint32_t(len / kDepthSampleBytes * sizeof(uint64_t)) : 0;
  const size_t at = log_reserve(len + plane_len);
  std::memcpy(&bytes_[at], old + (lo - pixel_addr), len);
  if (old_planes) std::memcpy(&bytes_[at + len], old_planes + (lo - pixel_addr) / kDepthSampleBytes, plane_len);
  pending_.push_back(Pending{tile, at, uint32_t(lo - tile_start), len, plane_len, uint8_t(b), false});
  ++pending_count_[size_t(b)][tile];
  // Ids count modulo 2^32 - 1, so that none is kNoPatch (pending_ holds fewer).
  const uint64_t id = uint64_t(first_id_) + pending_.size() - 1;
  return uint32_t(id >= kNoPatch ? id - kNoPatch : id);
}

void CompressionModel::applied(uint32_t id) {
  if (id == kNoPatch) return;
  Pending& p = pending_[size_t(id >= first_id_ ? id - first_id_ : uint64_t(id) + kNoPatch - first_id_)];
  p.applied = true;
  --pending_count_[p.buf][p.tile];
  if (!pending_.front().applied) return;
  do {
    pending_.pop_front();
    first_id_ = first_id_ + 1 == kNoPatch ? 0 : first_id_ + 1;  // modulo 2^32 - 1 (pend)
  } while (!pending_.empty() && pending_.front().applied);
  if (pending_.empty()) {
    bytes_head_ = bytes_end_ = 0;
    wrapped_ = false;
    return;
  }
  // The front's bytes are the log's oldest; below the end, the ring's upper part is free.
  bytes_head_ = pending_.front().at;
  if (wrapped_ && bytes_head_ < bytes_end_) wrapped_ = false;
}

size_t CompressionModel::log_reserve_past_top(size_t n) {
  if (!wrapped_ && n <= bytes_head_) {
    wrapped_ = true;
    bytes_end_ = n;
    return 0;
  }
  // Full: the pending writes' bytes in order into a ring twice the size.
  std::vector<uint8_t> w(std::max<size_t>({size_t{1} << 14, 2 * bytes_.size(), 2 * n}));
  size_t end = 0;
  pending_.for_each([&](Pending& p) {
    const size_t k = p.len + p.plane_len;
    std::memcpy(&w[end], &bytes_[p.at], k);
    p.at = end;
    end += k;
  });
  bytes_.swap(w);
  wrapped_ = false;
  bytes_head_ = 0;
  bytes_end_ = end + n;
  return end;
}

uint64_t CompressionModel::metadata(Buffer b, uint64_t tile, bool write, uint64_t now, uint32_t rop) {
  MetaCache& m = meta_[rop];
  // The state bits of the surface's tiles, packed, in the upper half of its
  // address space.
  const uint64_t addr = (uint64_t(b) << 48 | uint64_t{1} << 47) + tile * uint64_t(meta_bits_) / 8;
  const uint64_t line = addr & line_mask_;
  bool hit = line == m.last_line;
  const size_t way = hit ? m.last_way : m.tags.find(line, hit);
  m.last_line = line;
  m.last_way = way;
  uint64_t ready = now;
  if (hit) {
    ++s_.metadata_hits;
    ready = std::max(now, m.ready[way]);
  } else {
    ++s_.metadata_misses;
    const uint64_t old = m.tags.tag(way);
    if (old != CacheTags::kInvalid && m.dirty[way]) {
      const uint32_t draw = dram_->charged();
      dram_->charge_to(m.draw[way]);  // its last writer's (attribution.h)
      dram_->access(old, line_bytes_, true, Buffer((old >> 48) & 7u), now);
      dram_->charge_to(draw);
      s_.metadata_bytes_written[size_t((old >> 48) & 7u)] += line_bytes_;
    }
    m.tags.install(way, line);
    m.dirty[way] = 0;
    // The state bits start cleared with the surface (a clear writes them
    // once, before the frame); a miss reads the line.
    ready = m.ready[way] = dram_->access(line, line_bytes_, false, b, now);
    s_.metadata_bytes_read[size_t(b)] += line_bytes_;
  }
  if (write) {
    m.dirty[way] = 1;
    m.draw[way] = dram_->charged();
  }
  return ready;
}

TileInfo CompressionModel::warm_tile(Buffer b, uint64_t tile) {
  const TileInfo t = on_[size_t(b)] ? info(b, tile) : view(b, tile, false);
  if (b == Buffer::kDepth && hiz_) zmax_[tile] = t.max_depth;
  if (on_[size_t(b)] && !t.cleared) stored_[size_t(b)][tile] = uint8_t(1 + t.size_class);
  return t;
}

void CompressionModel::warm_metadata(uint64_t line, Buffer b, bool write, uint32_t rop) {
  MetaCache& m = meta_[rop];
  const uint64_t mline = metadata_line(line, b);
  bool hit = false;
  const size_t way = m.tags.find(mline, hit);
  m.last_line = mline;
  m.last_way = way;
  if (!hit) {
    m.tags.install(way, mline);
    m.dirty[way] = 0;
    m.ready[way] = 0;
  }
  if (write) m.dirty[way] = 1;
}

CompressionModel::WarmState CompressionModel::warm_state() const {
  WarmState w;
  for (size_t b = 0; b < size_t(kBuffers); ++b) w.stored[b] = stored_[b].to_vector();
  w.zmax = zmax_.to_vector();
  for (const MetaCache& m : meta_) {
    std::vector<uint64_t> tags(m.tags.size());
    for (size_t i = 0; i < tags.size(); ++i) tags[i] = m.tags.tag(i);
    w.meta_tags.push_back(std::move(tags));
    w.meta_dirty.push_back(m.dirty);
  }
  return w;
}

bool CompressionModel::write_back(uint64_t line, Buffer b, uint64_t now, uint32_t rop, uint64_t& done) {
  const uint64_t tile = tile_of(line, b);
  const TileInfo t = info(b, tile);
  if (b == Buffer::kDepth && hiz_) zmax_[tile] = t.max_depth;
  metadata(b, tile, true, now, rop);  // posted: the data write does not wait for it
  ++s_.lines_written[size_t(b)];
  s_.bytes_written_uncompressed[size_t(b)] += line_bytes_;
  if (t.cleared) {
    stored_[size_t(b)][tile] = 0;
    ++s_.writes_cleared[size_t(b)];
    done = now;
    return false;
  }
  stored_[size_t(b)][tile] = uint8_t(1 + t.size_class);
  ++s_.writes_per_class[size_t(b)][size_t(t.size_class)];
  const uint32_t bytes = std::max<uint32_t>(1, line_bytes_ >> t.size_class);
  s_.bytes_written[size_t(b)] += bytes;
  done = dram_->access(line, bytes, true, b, now + (t.size_class ? cfg_.compress_latency_cycles : 0));
  return true;
}

bool CompressionModel::stored_cleared(uint64_t line, Buffer b) const {
  return stored_[size_t(b)].get(tile_of(line, b)) == 0;
}

uint64_t CompressionModel::fill(uint64_t line, Buffer b, uint64_t now, uint32_t rop) {
  const uint64_t tile = tile_of(line, b);
  const uint64_t meta_ready = metadata(b, tile, false, now, rop);
  const uint8_t st = stored_[size_t(b)][tile];
  if (st == 0) return meta_ready;  // cleared: the clear value, no data read
  const int c = st == kNever ? 0 : st - 1;
  const uint32_t bytes = std::max<uint32_t>(1, line_bytes_ >> c);
  ++s_.lines_read[size_t(b)];
  s_.bytes_read_uncompressed[size_t(b)] += line_bytes_;
  s_.bytes_read[size_t(b)] += bytes;
  return dram_->access(line, bytes, false, b, meta_ready) + (c ? cfg_.decompress_latency_cycles : 0);
}

uint64_t CompressionModel::flush(uint64_t now) {
  uint64_t done = now;
  for (MetaCache& m : meta_)
    for (size_t w = 0; w < m.dirty.size(); ++w)
      if (m.dirty[w] && m.tags.tag(w) != CacheTags::kInvalid) {
        const Buffer b = Buffer((m.tags.tag(w) >> 48) & 7u);
        dram_->charge_to(m.draw[w]);
        done = std::max(done, dram_->access(m.tags.tag(w), line_bytes_, true, b, now));
        s_.metadata_bytes_written[size_t(b)] += line_bytes_;
        m.dirty[w] = 0;
      }
  return done;
}

bool CompressionModel::hiz_rejects(uint32_t x, uint32_t y, float zmin) {
  ++s_.hiz_tests;
  const uint64_t pix = (uint64_t(y >> 3) * tiles_x_ + (x >> 3)) * 64 + ((y & 7u) << 3 | (x & 7u));
  const bool reject = zmin > zmax_[pix / fmt_.tile_pixels];
  s_.hiz_rejected += reject;
  return reject;
}

}  // namespace ropsim
