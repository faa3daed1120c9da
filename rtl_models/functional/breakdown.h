// Where a run's counts come from: every counter split by the trace's draw
// ids, and the per-fragment counts summed per pixel (heat maps). Built from
// each fragment's counter delta (StochasticModel::set_counts_observer, the
// cycle model's retirement), so every draw's row and every map add up to
// the run's counters exactly. Fed on one thread, in API order.
#pragma once
#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <vector>

#include "rtl_models/algo/buffers.h"
#include "rtl_models/functional/counters.h"
#include "traces/format/trace.h"
#include "util/containers/tile_map.h"

namespace ropsim {

/// The per-pixel maps, each the sum of one counter over the pixel's
/// fragments; declared once (name = the counter's, the file name of the map).
#define ROPSIM_PIXEL_MAPS(X)                                                            \
  X(fragments, "fragments", "fragments at the pixel: its depth complexity")             \
  X(samples_tested, "samples", "covered samples tested at the pixel")                   \
  X(samples_depth_passed, "samples", "samples that passed the depth test at the pixel") \
  X(samples_written, "samples", "samples written at the pixel (depth and colour)")      \
  X(surface_id_changes, "events", "lk: new surfaces started at the pixel by a bitmask conflict")

enum class PixelMap {
#define ROPSIM_X(name, unit, meaning) name,
  ROPSIM_PIXEL_MAPS(ROPSIM_X)
#undef ROPSIM_X
};
constexpr int kPixelMaps = 0
#define ROPSIM_X(name, unit, meaning) +1
    ROPSIM_PIXEL_MAPS(ROPSIM_X)
#undef ROPSIM_X
    ;
/// The maps' descriptions, in declaration order (StatDesc: counters.h).
const std::vector<StatDesc>& pixel_map_descs();

/// What to break a run's counts down by (--per-draw, --maps).
struct BreakdownRequest {
  bool per_draw = false;
  bool per_pixel = false;
  bool any() const { return per_draw || per_pixel; }
};

class RunBreakdown {
 public:
  RunBreakdown(const TraceHeader& h, bool per_draw, bool per_pixel);
  bool per_draw() const { return per_draw_; }
  bool per_pixel() const { return per_pixel_; }

  /// One fragment and what it added to the counters.
  void add(const Fragment& f, const Counters& delta);
  /// Cycles attributed to a draw (the cycle model: the cycles up to the
  /// retirement of each of its fragments since the previous retirement).
  void add_cycles(uint32_t draw, uint64_t cycles);

  /// DRAM bytes charged to a draw per buffer (the cycle model).
  void add_dram(uint32_t draw, const std::array<uint64_t, kBuffers>& read,
                const std::array<uint64_t, kBuffers>& written);

  struct Draw {
    Counters counters;
    uint64_t cycles = 0;
    /// The cycle model: DRAM bytes per buffer charged to the draw (its
    /// fills, the write-backs of lines it wrote last: attribution.h).
    std::array<uint64_t, kBuffers> dram_read{}, dram_written{};
  };
  /// Every draw id that had a fragment, ascending.
  const std::map<uint32_t, Draw>& draws() const { return draws_; }
  /// The draws' counters and cycles summed.
  Draw total() const;

  /// Row y of a map (width values; 0 where no fragment landed).
  void row(PixelMap m, uint32_t y, float* out) const;
  /// A map's sum over the screen and its largest value.
  uint64_t sum(PixelMap m) const;
  uint32_t max(PixelMap m) const;
  uint32_t width() const { return width_; }
  uint32_t height() const { return height_; }

 private:
  struct Tile {
    std::array<std::array<uint32_t, 64>, kPixelMaps> v{};
  };
  uint32_t width_, height_;
  bool per_draw_, per_pixel_;
  std::map<uint32_t, Draw> draws_;
  Draw* last_draw_ = nullptr;
  uint32_t last_id_ = 0;
  TileMap<Tile> tiles_;
};

}  // namespace ropsim
