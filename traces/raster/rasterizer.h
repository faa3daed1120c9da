// A screen-space triangle rasterizer producing trace fragments in API order:
// fixed-point edge functions (8 sub-pixel bits), the top-left fill rule, and
// a depth plane per fragment (docs/trace-format.md "Depth planes").
#pragma once
#include <array>
#include <cstdint>
#include <functional>

#include "traces/format/trace.h"

namespace ropsim {

/// A vertex after projection and viewport: x, y in pixels (y down), z in [0, 1].
struct ScreenVertex {
  double x = 0, y = 0, z = 0;
  std::array<float, 3> rgb{1.0f, 1.0f, 1.0f};
  float alpha = 1.0f;
  double inv_w = 1.0;  ///< 1 / clip w, used only when the triangle is `perspective`
};

struct ScreenTriangle {
  std::array<ScreenVertex, 3> v;
  uint32_t draw_id = 0;
  uint32_t prim_id = 0;
  /// Interpolate colour and opacity perspective-correctly (with the vertices'
  /// inv_w) instead of linearly in screen space. Coverage and depth are the same.
  bool perspective = false;
  /// Take the depth plane from the unsnapped vertex positions (as Mesa's
  /// llvmpipe does) instead of the ones snapped to 1/256 pixel. Coverage
  /// always uses the snapped positions.
  bool depth_from_unsnapped = false;
};

struct RasterStats {
  uint64_t triangles = 0, culled_degenerate = 0, fragments = 0, covered_samples = 0;
};

class Rasterizer {
 public:
  static constexpr int kSubpixelBits = 8;

  explicit Rasterizer(const TraceHeader& header);
  /// Emits one fragment per pixel with at least one covered sample, in
  /// scanline order. Attributes are interpolated at the centroid of the
  /// covered samples (which lies inside the triangle).
  void rasterize(const ScreenTriangle& t, const std::function<void(const Fragment&)>& emit);
  const RasterStats& stats() const { return stats_; }

 private:
  const TraceHeader& h_;
  RasterStats stats_;
};

}  // namespace ropsim
