// Whom a cycle run's costs are charged to (--per-draw, --maps with the cycle
// model; docs/reports.md "Per draw and per pixel"): the DRAM bytes by draw
// and buffer, and by distributor tile the ROP cache misses and every unit's
// cycles per activity. Observation only: no model decision reads it, so the
// run's figures are those of a run without it.
//
// The rules, each summing exactly to a report counter:
//  - a DRAM read (a line fill, and the state bits a compressed surface's
//    fill reads) is charged to the draw of the fragment whose cache miss
//    caused it;
//  - a DRAM write (a dirty line evicted or flushed at the end of a pass, and
//    a metadata line likewise) is charged to the draw that last wrote the
//    line: the draw whose data it carries, whichever fragment's miss evicted
//    it. So the end-of-frame flush needs no row of its own;
//  - a cache miss (read or write lookup) is charged to the tile of the
//    fragment that made the lookup;
//  - a unit's cycles in each activity are charged to the tile of the
//    fragment it took from its input last (the trace source: produced last),
//    switching at the cycle it takes the next one; the cycles before a
//    unit's first fragment go to that fragment's tile. A unit that never
//    takes a fragment charges no tile (unowned()).
// No SystemC here: the memory and core layers charge it, the top owns it
// across passes.
#pragma once
#include <array>
#include <cstdint>
#include <map>
#include <vector>

#include "rtl_models/algo/buffers.h"
#include "rtl_models/observe/interval_log.h"

namespace ropsim {

/// Whom an access is charged to: the draw id and the distributor tile
/// (ty * tiles_x + tx) of the fragment that made it.
struct Owner {
  uint32_t draw = 0;
  uint32_t tile = 0;
};

/// DRAM bytes per buffer.
struct DramBytes {
  std::array<uint64_t, kBuffers> read{}, written{};
};

class Attribution {
 public:
  static constexpr int kActivities = kIntervalActivities;
  /// per_draw: DRAM bytes by draw; tiles > 0: the per-tile figures of that
  /// many distributor tiles.
  Attribution(bool per_draw, uint32_t tiles)
      : per_draw_(per_draw), misses_(tiles), retire_cycles_(tiles), tiles_(tiles) {
    for (auto& a : unit_cycles_) a.assign(tiles, 0);
  }
  bool per_draw() const { return per_draw_; }
  uint32_t tiles() const { return tiles_; }

  /// (Out of line, attribution.cpp: the DRAM's access stays small.)
  void dram(uint32_t draw, bool write, Buffer b, uint64_t bytes);
  void cache_miss(uint32_t tile) {
    if (tiles_) ++misses_[tile];
  }
  void unit_cycles(uint32_t tile, int activity, uint64_t n) {
    if (tiles_) unit_cycles_[size_t(activity)][tile] += n;
  }
  /// Cycles of a unit that never took a fragment.
  void unowned_cycles(int activity, uint64_t n) { unowned_[size_t(activity)] += n; }
  void retire_cycles(uint32_t tile, uint64_t n) {
    if (tiles_) retire_cycles_[tile] += n;
  }

  /// DRAM bytes per draw id (the draws with traffic), ascending.
  const std::map<uint32_t, DramBytes>& dram_by_draw() const { return by_draw_; }
  /// Per tile: cache misses, the cycles of the retirements (like a draw's
  /// cycles), and the units' cycles in each activity.
  const std::vector<uint64_t>& cache_misses() const { return misses_; }
  const std::vector<uint64_t>& retire_cycles() const { return retire_cycles_; }
  const std::vector<uint64_t>& unit_cycles(int activity) const { return unit_cycles_[size_t(activity)]; }
  uint64_t unowned(int activity) const { return unowned_[size_t(activity)]; }

 private:
  bool per_draw_;
  std::map<uint32_t, DramBytes> by_draw_;
  DramBytes* last_ = nullptr;
  uint32_t last_draw_ = 0;
  std::vector<uint64_t> misses_, retire_cycles_;
  std::array<std::vector<uint64_t>, kActivities> unit_cycles_;
  std::array<uint64_t, kActivities> unowned_{};
  uint32_t tiles_;
};

}  // namespace ropsim
