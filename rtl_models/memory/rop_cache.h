// The ROP cache of one ROP unit: set-associative, LRU, write-back, holding
// depth, colour and tracker lines. Reads allocate and fill from DRAM; writes
// allocate without a fill (a ROP writes whole samples and keeps byte masks),
// so colour, which is written but never read, costs no DRAM reads. With
// fast_clear, a line never written to DRAM reads as the clear value at hit
// latency (the clear state lives in on-chip tags, as real ROPs' fast clear).
// A passive timing model called by the units at the current cycle; a read of
// a line whose fill is in flight waits for that fill (MSHR merge).
#pragma once
#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

#include "rtl_models/config/hw_config.h"
#include "rtl_models/memory/address_map.h"
#include "rtl_models/memory/cache_tags.h"
#include "rtl_models/memory/compression_model.h"
#include "rtl_models/memory/dram.h"
#include "rtl_models/memory/line_set.h"
#include "util/containers/sorted_ring.h"

namespace ropsim {

struct CacheStats {
  std::array<uint64_t, kBuffers> read_hits{}, read_misses{}, write_hits{}, write_misses{};
  uint64_t merged = 0;  ///< reads of a line whose fill was still in flight
  uint64_t evictions = 0, dirty_evictions = 0;
  uint64_t clear_fills = 0;  ///< misses served by fast clear, no DRAM read
  /// Writes that made a clean line dirty: each is one line written to DRAM
  /// later, at its eviction or the final flush.
  uint64_t dirtied = 0;
  std::array<uint64_t, kBuffers> dirtied_of{};  ///< dirtied, per surface

  /// Sums another cache's counts into this one (the ROP caches' total).
  CacheStats& operator+=(const CacheStats& o) {
    for (size_t b = 0; b < size_t(kBuffers); ++b) {
      read_hits[b] += o.read_hits[b];
      read_misses[b] += o.read_misses[b];
      write_hits[b] += o.write_hits[b];
      write_misses[b] += o.write_misses[b];
    }
    merged += o.merged;
    evictions += o.evictions;
    dirty_evictions += o.dirty_evictions;
    clear_fills += o.clear_fills;
    dirtied += o.dirtied;
    for (size_t b = 0; b < size_t(kBuffers); ++b) dirtied_of[b] += o.dirtied_of[b];
    return *this;
  }
  /// Read and write hits (misses) over every buffer.
  uint64_t hits() const {
    uint64_t n = 0;
    for (size_t b = 0; b < size_t(kBuffers); ++b) n += read_hits[b] + write_hits[b];
    return n;
  }
  uint64_t misses() const {
    uint64_t n = 0;
    for (size_t b = 0; b < size_t(kBuffers); ++b) n += read_misses[b] + write_misses[b];
    return n;
  }
  double hit_rate() const { return hits() + misses() ? double(hits()) / double(hits() + misses()) : 0.0; }
};

class RopCache;

/// Writes posted by the writeback units of all ROPs, applied to their caches
/// in the order (cycle, ROP, post order) before any memory access at a later
/// cycle: so a write and a read in the same cycle never depend on the order
/// SystemC runs their units in, and a decoupled writeback (unit.h) may post
/// ahead of SystemC time.
class PostedWrites {
 public:
  /// Each ROP posts in non-decreasing cycle order (its writeback is in order).
  void post(uint64_t cycle, uint32_t rop, RopCache* cache, uint64_t line, Buffer b, Owner o = {},
            uint32_t patch = CompressionModel::kNoPatch) {
    if (rop >= q_.size()) q_.resize(rop + 1);
    q_[rop].cache = cache;  // one per ROP: the writes need not carry it
    q_[rop].writes.push(Write{cycle, line, o, b, patch});
    earliest_ = std::min(earliest_, cycle);
  }
  /// Applies every write posted for a cycle before `cycle`.
  void apply_before(uint64_t cycle) {
    if (earliest_ < cycle) apply(cycle);
  }
  void apply_all() { apply(~uint64_t{0}); }

 private:
  struct Write {
    uint64_t cycle;
    uint64_t line;
    Owner owner;
    Buffer buf;
    uint32_t patch;  // CompressionModel::pend's id, or kNoPatch
  };
  struct Earlier {
    bool operator()(const Write& a, const Write& b) const { return a.cycle < b.cycle; }
  };
  // Per ROP: its writes in post order, which is cycle order (pushes land at
  // the back; equal cycles keep their order).
  using Queue = SortedRing<Write, Earlier>;
  void apply(uint64_t before);
  struct PerRop {
    Queue writes;
    RopCache* cache = nullptr;
  };
  std::vector<PerRop> q_;
  uint64_t earliest_ = ~uint64_t{0};
};

class RopCache {
 public:
  /// `posted` (shared by the ROPs) delays writes as PostedWrites says; without
  /// it a posted write is applied at once.
  RopCache(const HwConfig::Cache& cfg, Dram& dram, LineSet& in_dram, PostedWrites* posted = nullptr, uint32_t rop = 0);
  /// Reads a line at cycle now for a fragment of `o`; returns the cycle its
  /// data is available.
  uint64_t read(uint64_t line_addr, Buffer b, uint64_t now, Owner o = {});
  /// Writes (part of) a line at cycle now; never stalls the writer.
  void write(uint64_t line_addr, Buffer b, uint64_t now, Owner o = {});
  /// Posts a write for cycle `cycle` (see PostedWrites); `patch`: what its
  /// functional write replaced (CompressionModel::pend), released once applied.
  void post_write(uint64_t line_addr, Buffer b, uint64_t cycle, Owner o = {},
                  uint32_t patch = CompressionModel::kNoPatch) {
    if (posted_) {
      posted_->post(cycle, rop_, this, line_addr, b, o, patch);
    } else {
      write(line_addr, b, cycle, o);
      applied(patch);
    }
  }
  /// A posted write was applied: its patch is released.
  void applied(uint32_t patch) {
    if (patch != CompressionModel::kNoPatch) comp_->applied(patch);
  }
  /// Also charges its misses and its DRAM traffic in attr (attribution.h's
  /// rules); the DRAM must attribute to the same.
  void attribute_to(Attribution* attr) { attr_ = attr; }
  /// Tag-only warming before a run (sampled simulation): the access's effect
  /// on the tags, the LRU order and the dirty bits, without time, DRAM
  /// traffic or statistics; a dirty line it evicts is recorded as in DRAM.
  /// With compression, a fill and a write-back also warm the metadata cache
  /// (tag-only), and a dirty line evicted takes its tile's other dirty lines.
  void warm(uint64_t line_addr, bool write, Buffer b);
  /// Writes every dirty line back at cycle now; returns the last completion.
  uint64_t flush(uint64_t now);
  const CacheStats& stats() const { return s_; }
  /// Also counts every lookup's hit or miss in log's row of its cycle (--stats-interval).
  void log_to(IntervalLog* log) { log_ = log; }
  /// Stores the compressed surfaces through comp (compression_model.h).
  void compress_with(CompressionModel* comp) { comp_ = comp; }
  CompressionModel* compression() const { return comp_; }
  /// The host bytes a way's state takes apart from its tag (CacheTags::bytes_per_way), per way (memory_estimate.h).
  static uint64_t way_state_bytes() { return sizeof(Way); }

 private:
  IntervalLog* log_ = nullptr;
  // A way's state apart from its tag (CacheTags), so a set's tags share one host cache line.
  struct Way {
    uint64_t ready = 0;
    uint32_t draw = 0;  // the draw that wrote the line last (its write-back's, attribution.h)
    Buffer buf : 8;     // its surface (a value-initialized way's is kDepth)
    bool dirty = false;
  };
  static_assert(sizeof(Way) == 16, "a way's state packs into 16 bytes");
  Attribution* attr_ = nullptr;
  /// The way (index) holding line, allocated (after an eviction) on a miss.
  size_t lookup(uint64_t line, bool& hit, uint64_t now);
  void evict(size_t way, uint64_t now);
  /// A dirty line to DRAM at cycle now; returns when it is written.
  uint64_t write_back(uint64_t line, Buffer b, uint64_t now);
  CompressionModel* comp_ = nullptr;
  bool warming_ = false;  // warm(): evictions move no data and count nothing
  HwConfig::Cache cfg_;
  Dram& dram_;
  LineSet& in_dram_;  // lines DRAM holds (shared by all caches)
  PostedWrites* posted_;
  uint32_t rop_;
  CacheTags tags_;
  std::vector<Way> ways_;
  CacheStats s_;
};

}  // namespace ropsim
