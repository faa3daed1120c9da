// The ROP cache's tags and replacement, written once: the set a line maps to,
// a hit's LRU refresh, and the way a miss takes (the set's first invalid way,
// else its least recently used). The cycle model's RopCache and the
// analytical model's tag-only cache both hold one, so they place every line
// alike. No SystemC; the caller moves the data and counts the traffic.
#pragma once
#include <cstddef>
#include <cstdint>
#include <vector>

#include "rtl_models/algo/bits.h"
#include "rtl_models/config/hw_config.h"

namespace ropsim {

class CacheTags {
 public:
  static constexpr uint64_t kInvalid = ~uint64_t{0};

  explicit CacheTags(const HwConfig::Cache& cfg)
      : ways_(cfg.ways),
        sets_(cfg.size_bytes / (cfg.line_bytes * cfg.ways)),
        set_shift_(uint32_t(log2_ceil(cfg.line_bytes))),
        tags_(size_t(cfg.size_bytes / cfg.line_bytes), kInvalid),
        lru_(tags_.size(), 0) {}

  /// The way holding line (hit = true, its LRU refreshed), or the way a miss
  /// takes (hit = false): the set's first invalid way, else its least
  /// recently used. On a miss the way still holds its old line (tag()), for
  /// the caller to evict before install(). One pass: an empty way's last use
  /// is 0 and a held line's at least 1, so the first way of least last use
  /// is the first invalid one when there is one.
  size_t find(uint64_t line, bool& hit) {
    const size_t base = set_base(line);
    const uint64_t* tag = &tags_[base];
    const uint64_t* lru = &lru_[base];
    size_t victim = 0;
    uint64_t oldest = lru[0];
    for (uint32_t i = 0; i < ways_; ++i) {
      if (tag[i] == line) {
        hit = true;
        lru_[base + i] = ++tick_;
        return base + i;
      }
      if (lru[i] < oldest) {
        oldest = lru[i];
        victim = i;
      }
    }
    hit = false;
    return base + victim;
  }
  /// The way holding line, or kNone; no LRU change (a probe).
  static constexpr size_t kNone = ~size_t{0};
  size_t probe(uint64_t line) const {
    const size_t base = set_base(line);
    for (uint32_t i = 0; i < ways_; ++i)
      if (tags_[base + i] == line) return base + i;
    return kNone;
  }
  /// Puts line in way (a miss's, its old line evicted), most recently used.
  void install(size_t way, uint64_t line) {
    tags_[way] = line;
    lru_[way] = ++tick_;
  }
  /// Empties way (its line evicted).
  void invalidate(size_t way) {
    tags_[way] = kInvalid;
    lru_[way] = 0;
  }
  uint64_t tag(size_t way) const { return tags_[way]; }
  size_t size() const { return tags_.size(); }  ///< ways over every set
  /// The ways of a cache of cfg (over every set), and the host bytes each
  /// takes here: its tag and its last use (memory_estimate.h).
  static uint64_t ways_of(const HwConfig::Cache& cfg) { return cfg.size_bytes / cfg.line_bytes; }
  static uint64_t bytes_per_way() { return sizeof(decltype(tags_)::value_type) + sizeof(decltype(lru_)::value_type); }

 private:
  /// The first way of line's set.
  size_t set_base(uint64_t line) const {
    const uint64_t l = line >> set_shift_;
    return size_t((l ^ (l >> 11) ^ (line >> 48) * 0x9e37u) & (sets_ - 1)) * ways_;
  }
  uint32_t ways_;
  uint64_t sets_;
  uint32_t set_shift_;
  std::vector<uint64_t> tags_;  // per way, kInvalid when empty
  std::vector<uint64_t> lru_;   // per way: last use (tick; 0 when empty), next to the tags for the victim search
  uint64_t tick_ = 0;
};

}  // namespace ropsim
