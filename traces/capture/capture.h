// Capture: a mesh scene (scene_file.h) -> clip-space triangles in API order
// (camera, object transforms, diffuse shading, opacity, draw order) -> near /
// far / guard-band clipping -> the fixed-point Rasterizer -> trace fragments.
// docs/capture.md describes every rule.
#pragma once
#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "traces/capture/scene_file.h"
#include "traces/capture/texture.h"
#include "traces/format/trace.h"
#include "traces/raster/rasterizer.h"

namespace ropsim {

/// A shaded vertex in clip space (D3D-style depth: 0 <= z <= w inside).
/// Stored as binary32 so that this rasterizer and Mesa see the same inputs.
struct ClipVertex {
  std::array<float, 4> pos{0, 0, 0, 1};  ///< x, y, z, w
  std::array<float, 3> rgb{1, 1, 1};     ///< linear, shaded
  float alpha = 1.0f;
};

struct ClipTriangle {
  std::array<ClipVertex, 3> v;
  uint32_t prim_id = 0;    ///< gl_PrimitiveID: index within the draw, in API order
  bool discarded = false;  ///< alphaMode MASK below the cutoff: drawn, every fragment discarded
  /// Textured: the vertices' rgb hold (u, v, diffuse shade) instead of a
  /// colour; each fragment samples texture `texture` of the draw at its
  /// (u, v) and gets colour = tint x shade x texel.rgb (if tex_rgb), opacity
  /// = alpha x texel.a (if tex_alpha); with `mask`, fragments below `cutoff`
  /// are discarded and the others are opaque (glTF alphaMode MASK).
  int texture = -1;
  std::array<float, 3> tint{1, 1, 1};
  bool tex_rgb = false, tex_alpha = false, mask = false;
  float cutoff = 0.5f;
};

/// One object = one draw call; triangles in submission order.
struct PreparedDraw {
  std::string name;
  bool back_faces = true;
  std::vector<ClipTriangle> triangles;
  std::vector<Texture> textures;
};

struct PreparedScene {
  SceneSpec spec;
  std::vector<PreparedDraw> draws;
  uint64_t triangles() const;
};

/// Loads the meshes and turns the scene into clip-space draws. Throws CaptureError.
PreparedScene prepare_scene(const SceneSpec& spec);

/// The trace header a capture writes: the scene's size, spp, formats and the
/// standard sample positions (docs/trace-format.md section 6).
TraceHeader capture_header(const SceneSpec& spec);

struct CaptureStats {
  uint64_t triangles = 0;            ///< submitted (discarded ones included)
  uint64_t discarded = 0;            ///< alphaMode MASK below the cutoff (whole triangles)
  uint64_t discarded_fragments = 0;  ///< textured alphaMode MASK: fragments below the cutoff
  uint64_t outside = 0;              ///< entirely outside a clip plane
  uint64_t clipped = 0;              ///< crossing a clip plane (near, far or guard band) and split
  uint64_t back_facing = 0;          ///< culled (objects with back_faces = false)
  uint64_t degenerate = 0;           ///< zero area after snapping to 1/256 pixel
  uint64_t fragments = 0, covered_samples = 0;
  double seconds = 0;
};

/// Rasterizes the prepared scene with header h (its size, spp and positions)
/// and calls emit(fragment) in API order. progress(done, total) is called now
/// and then with triangles done.
CaptureStats rasterize_prepared(const PreparedScene& ps, const TraceHeader& h,
                                const std::function<void(const Fragment&)>& emit,
                                const std::function<void(uint64_t, uint64_t)>& progress = {});

/// Scene file -> trace file (atomically: no file on error). A capture with no
/// fragment is an error naming the scene ("nothing visible") unless allow_empty.
CaptureStats capture_to_file(const SceneSpec& spec, const std::string& out_path, bool allow_empty = false,
                             const std::function<void(uint64_t, uint64_t)>& progress = {});

}  // namespace ropsim
