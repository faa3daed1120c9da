// The ROP cache of one ROP unit: set-associative, LRU, write-back, holding
// depth, colour and tracker lines. Reads allocate and fill from DRAM; writes
// allocate without a fill (a ROP writes whole samples and keeps byte masks),
// so colour, which is written but never read, costs no DRAM reads. With
// fast_clear, a line never written to DRAM reads as the clear value at hit
// latency (the clear state lives in on-chip tags, as real ROPs' fast clear).
// A passive timing model called by the units at the current cycle; a read of
// a line whose fill is in flight waits for that fill (MSHR merge).
#pragma once
#include <array>
#include <cstdint>
#include <unordered_set>
#include <vector>

#include "address_map.h"
#include "dram.h"
#include "hw_config.h"

namespace ropsim {

struct CacheStats {
  std::array<uint64_t, kBuffers> read_hits{}, read_misses{}, write_hits{}, write_misses{};
  uint64_t merged = 0;      ///< reads of a line whose fill was still in flight
  uint64_t evictions = 0, dirty_evictions = 0;
  uint64_t clear_fills = 0; ///< misses served by fast clear, no DRAM read
};

class RopCache {
 public:
  RopCache(const HwConfig::Cache& cfg, Dram& dram, std::unordered_set<uint64_t>& in_dram);
  /// Reads a line at cycle now; returns the cycle its data is available.
  uint64_t read(uint64_t line_addr, Buffer b, uint64_t now);
  /// Writes (part of) a line at cycle now; posted, never stalls the writer.
  void write(uint64_t line_addr, Buffer b, uint64_t now);
  /// Writes every dirty line back at cycle now; returns the last completion.
  uint64_t flush(uint64_t now);
  const CacheStats& stats() const { return s_; }

 private:
  struct Way {
    uint64_t tag = 0, lru = 0, ready = 0;
    Buffer buf = Buffer::kDepth;
    bool valid = false, dirty = false;
  };
  Way& lookup(uint64_t line, bool& hit, uint64_t now);
  void evict(Way& w, uint64_t now);
  HwConfig::Cache cfg_;
  Dram& dram_;
  std::unordered_set<uint64_t>& in_dram_;  // lines DRAM holds (shared by all caches)
  uint32_t sets_, set_shift_;
  std::vector<Way> ways_;
  uint64_t tick_ = 0;
  CacheStats s_;
};

}  // namespace ropsim
