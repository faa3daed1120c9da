// Built-in procedural scenes (docs/scenes.md), generated deterministically
// from a seed as screen-space triangles in API order and rasterized to traces.
#pragma once
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "traces/format/trace.h"
#include "traces/raster/rasterizer.h"
#include "util/errors.h"

namespace ropsim {

struct SceneInfo {
  std::string name;
  std::string description;
  uint32_t width, height;  ///< default resolution
};

/// The catalogue of built-in scenes, in a fixed order.
const std::vector<SceneInfo>& scene_catalog();

class SceneError : public UserError {
 public:
  using UserError::UserError;
};

struct SceneParams {
  std::string name = "cloth";
  int spp = 16;
  uint32_t width = 0, height = 0;  ///< 0 = the scene's default
  uint64_t seed = 1;
  DepthMode depth_mode = DepthMode::kPlane;
  ColorFormat color_format = ColorFormat::kRgbF32;
  Compression compression = Compression::kZstd;
  bool checksum = true;  ///< checksummed payload blocks (docs/trace-format.md section 2.3)
};

struct Scene {
  TraceHeader header;
  std::vector<ScreenTriangle> triangles;  ///< in API order
};

/// Builds a scene; throws SceneError for an unknown name or bad parameters.
Scene build_scene(const SceneParams& p);

/// Rasterizes every triangle of the scene in API order.
RasterStats rasterize_scene(const Scene& s, const std::function<void(const Fragment&)>& emit);

/// Builds the scene and writes it as a trace file (atomically).
RasterStats write_scene_trace(const SceneParams& p, const std::string& path);

}  // namespace ropsim
