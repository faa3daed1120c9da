// A frame's statistics by the draws' kinds (draw_state.h): draws, fragments
// and covered samples per kind, and the transparent part (src-over and
// premultiplied-over draws): its share of the covered samples and of the
// screen, its depth complexity, and its translucent fragments (alpha below
// 1). `ropsim trace info` prints them; a report of a frame of draw states
// carries them (`frame.*`). Streams: its memory is per-pixel counters of
// the touched 8 x 8 tiles.
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "traces/format/draw_state.h"
#include "traces/format/trace.h"
#include "util/containers/tile_map.h"

namespace ropsim {

/// The kinds a frame's statistics call transparent: the over operators.
constexpr bool is_transparent_kind(DrawKind k) { return k == DrawKind::kSrcOver || k == DrawKind::kPremultipliedOver; }

struct FrameStats {
  uint64_t fragments = 0, covered = 0;  ///< every fragment; their covered samples
  uint64_t screen_samples = 0;          ///< width x height x spp
  std::array<uint64_t, kDrawKinds> kind_draws{}, kind_fragments{}, kind_covered{};
  // The transparent part.
  uint64_t transparent_covered = 0;    ///< its covered samples (a sample once per fragment)
  uint64_t transparent_pixels = 0;     ///< pixels one of its fragments touches
  uint64_t transparent_fragments = 0;  ///< its fragments
  uint64_t transparent_max = 0;        ///< its most fragments in one pixel
  uint64_t transparent_samples = 0;    ///< distinct samples one of its fragments covers
  uint64_t translucent_fragments = 0;  ///< its fragments at alpha below 1
  uint64_t translucent_covered = 0;    ///< their covered samples

  double transparent_share() const { return covered ? double(transparent_covered) / double(covered) : 0.0; }
  double translucent_share() const { return covered ? double(translucent_covered) / double(covered) : 0.0; }
  double transparent_screen_share() const {
    return screen_samples ? double(transparent_samples) / double(screen_samples) : 0.0;
  }
  double transparent_per_pixel() const {
    return transparent_pixels ? double(transparent_fragments) / double(transparent_pixels) : 0.0;
  }
  /// The transparent part's depth complexity: its fragments over each sample
  /// it covers, the mean.
  double transparent_per_sample() const {
    return transparent_samples ? double(transparent_covered) / double(transparent_samples) : 0.0;
  }
};

/// Counts a frame's fragments as they stream by.
class FrameStatsCounter {
 public:
  explicit FrameStatsCounter(const TraceHeader& h);
  void add(const Fragment& f);
  /// The statistics of the fragments added (the draws per kind: the table's
  /// states; without a table every draw id up to the largest, of the
  /// default state's kind).
  FrameStats finish() const;

 private:
  struct Transparent {
    std::array<uint32_t, 64> n{};
    std::array<uint64_t, 64> covered{};
  };
  const DrawTable& table_;
  std::vector<DrawKind> kind_of_;
  DrawKind default_kind_;
  TileMap<Transparent> see_through_;
  FrameStats s_;
  uint32_t max_draw_ = 0;
};

/// The statistics of a whole trace file (streams it once).
FrameStats frame_stats_of(const std::string& trace_path);

}  // namespace ropsim
