// The analytical model's ROP cache (--fidelity approximate), tag-only: the
// cycle model's RopCache placement and write policy (rop_cache.h) without
// data or time of its own.
#pragma once
#include <algorithm>
#include <cstdint>
#include <vector>

#include "rtl_models/algo/buffers.h"
#include "rtl_models/config/hw_config.h"
#include "rtl_models/memory/cache_tags.h"
#include "rtl_models/memory/line_set.h"
#include "rtl_models/memory/rop_cache.h"
#include "rtl_models/memory/tag_compression.h"
#include "rtl_models/memory/tag_dram.h"

namespace ropsim {

/// One ROP cache's tags, as RopCache holds them: the same sets (the same
/// index function), ways, LRU replacement, read-allocate with a fill,
/// write-allocate without one, fast clear from the lines DRAM holds, and the
/// final flush in way order. Its misses and write-backs go to the DRAM model
/// (dram.h: the channel, bank and row map, the row buffers, each channel's
/// bursts served in arrival order) at the cycle the model estimates for the
/// access. With compression (comp), the compressed surfaces' fills and
/// write-backs move their tiles' compressed bytes and the state bits
/// (approx_compression.h), and a dirty line's eviction writes its tile's
/// other dirty lines with it, as RopCache does.
class TagOnlyCache {
 public:
  /// The bytes of one way's state (the memory estimate counts them).
  static constexpr size_t kWayBytes = 24;
  enum class Read { kHit, kClearFill, kMiss };
  /// window: the depth test's outstanding fragments (depth_test.max_outstanding);
  /// rop: the cache's ROP (its metadata cache).
  TagOnlyCache(const HwConfig::Cache& cfg, uint32_t window, DramTags& dram, LineSet& in_dram, TagOnlyCompression* comp,
               uint32_t rop)
      : window_(window),
        cfg_(cfg),
        dram_(dram),
        in_dram_(in_dram),
        comp_(comp),
        rop_(rop),
        tags_(cfg),
        ways_(tags_.size()) {}

  /// A read; latency: the cycles until its data is there, unloaded.
  Read read(uint64_t line, Buffer b, uint64_t& latency) {
    bool hit = false;
    Way& w = ways_[lookup(line, hit)];
    if (hit) {
      ++s_.read_hits[size_t(b)];
      latency = cfg_.hit_latency_cycles;
      // A hit on a line whose fill is still in flight waits for it (the
      // cache's MSHR merge). The fill is in flight while its fragment waits
      // in the depth test: for the next `window` fragments of this ROP, the
      // k-th of which (entering k / window of a fill's latency later, when
      // the depth test's slots turn over once per fill) waits the rest. Not a
      // fragment of the same pixel: pixel ordering issued it only after the
      // filling fragment retired, its data there.
      const uint64_t k = seq_ - w.fill_seq;
      if (w.fill_seq != kNoFill && k > 0 && k < window_ && w.fill_pixel != pixel_) {
        ++s_.merged;
        latency = std::max<uint64_t>(latency, w.fill_latency * (window_ - k) / window_);
      }
      return Read::kHit;
    }
    ++s_.read_misses[size_t(b)];
    w.buf = b;
    w.dirty = false;
    w.fill_seq = kNoFill;
    if (cfg_.fast_clear && !in_dram_.contains(line)) {
      ++s_.clear_fills;
      latency = cfg_.hit_latency_cycles;
      return Read::kClearFill;
    }
    if (comp_ && comp_->compresses(b))
      latency = comp_->fill(line, b, rop_) + cfg_.hit_latency_cycles;
    else
      latency = dram_.access(line, cfg_.line_bytes, false, b, 0) + cfg_.hit_latency_cycles;
    w.fill_seq = seq_;
    w.fill_latency = uint32_t(latency);
    w.fill_pixel = pixel_;
    return Read::kMiss;
  }
  void write(uint64_t line, Buffer b) {
    bool hit = false;
    Way& w = ways_[lookup(line, hit)];
    if (hit) {
      ++s_.write_hits[size_t(b)];
    } else {
      ++s_.write_misses[size_t(b)];
      w.buf = b;
      w.fill_seq = kNoFill;
    }
    if (!w.dirty) ++s_.dirtied;
    w.dirty = true;
    if (comp_) comp_->touched(line, b);
  }
  void flush() {
    for (size_t i = 0; i < ways_.size(); ++i)
      if (Way& w = ways_[i]; tags_.tag(i) != CacheTags::kInvalid && w.dirty) {
        write_back(tags_.tag(i), w.buf);
        w.dirty = false;
      }
  }
  /// The next fragment of this ROP, at pixel key `pixel` (its reads follow).
  void next_fragment(uint32_t pixel) {
    ++seq_;
    pixel_ = pixel;
  }
  const CacheStats& stats() const { return s_; }

 private:
  static constexpr uint64_t kNoFill = ~uint64_t{0};
  struct Way {
    uint64_t fill_seq = kNoFill;  // the fragment whose read filled it from DRAM
    uint32_t fill_latency = 0;    // that fill's latency
    uint32_t fill_pixel = 0;      // that fragment's pixel
    Buffer buf = Buffer::kDepth;
    bool dirty = false;
  };
  static_assert(sizeof(Way) == kWayBytes, "kWayBytes is a way's size");
  // The cycle model's placement (cache_tags.h); a miss evicts the way's line.
  size_t lookup(uint64_t line, bool& hit) {
    const size_t victim = tags_.find(line, hit);
    if (hit) return victim;
    if (const uint64_t old = tags_.tag(victim); old != CacheTags::kInvalid) {
      ++s_.evictions;
      if (ways_[victim].dirty) {
        ++s_.dirty_evictions;
        const Buffer b = ways_[victim].buf;
        write_back(old, b);
        // A compressed tile leaves as a block: the tile's other dirty lines
        // are written back with it (and stay, clean).
        if (comp_ && comp_->compresses(b)) {
          uint64_t first = 0, count = 0;
          comp_->tile_lines(old, b, first, count);
          for (uint64_t k = 0; k < count; ++k) {
            const uint64_t other = first + k * cfg_.line_bytes;
            if (other == old) continue;
            const size_t ow = tags_.probe(other);
            if (ow == CacheTags::kNone || !ways_[ow].dirty || ways_[ow].buf != b) continue;
            write_back(other, b);
            ways_[ow].dirty = false;
          }
        }
      }
      ways_[victim].dirty = false;
    }
    tags_.install(victim, line);
    return victim;
  }
  /// A dirty line to DRAM: compressed (a cleared tile writes no data and
  /// stays out of DRAM: a later fill is a clear fill), or whole.
  void write_back(uint64_t line, Buffer b) {
    if (comp_ && comp_->compresses(b)) {
      if (comp_->write_back(line, b, rop_)) in_dram_.insert(line);
      return;
    }
    if (comp_ && b == Buffer::kDepth) comp_->depth_written_back(line);  // Hi-Z alone
    dram_.access(line, cfg_.line_bytes, true, b, 0);
    in_dram_.insert(line);
  }
  uint64_t window_, seq_ = 0;
  uint32_t pixel_ = 0;
  HwConfig::Cache cfg_;
  DramTags& dram_;
  LineSet& in_dram_;
  TagOnlyCompression* comp_;
  uint32_t rop_;
  CacheTags tags_;
  std::vector<Way> ways_;
  CacheStats s_;
};

}  // namespace ropsim
