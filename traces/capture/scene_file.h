// Mesh scene files (TOML, docs/capture.md "Scene file"): meshes, per-object
// opacity and colour, camera, light, resolution, spp and draw order. The file
// is parsed into optional fields, then defaults are resolved into the plain
// SceneSpec below. An unknown key or a bad value is a CaptureError naming the
// file, the line and the key.
#pragma once
#include <array>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "traces/format/trace.h"
#include "util/errors.h"

namespace ropsim {

/// A user error in a capture (scene file, mesh, camera): one line naming the
/// file and the key or record.
class CaptureError : public UserError {
 public:
  using UserError::UserError;
};

using Vec3d = std::array<double, 3>;

enum class ObjectKind { kMesh, kBillboards };
enum class OpacitySource { kConstant, kMaterial };
enum class ColorSource { kConstant, kMaterial, kVertex };
/// The order of a draw's triangles: as authored in the file; a seeded
/// permutation; or sorted by the view depth of their centroids (stable).
enum class DrawOrder { kAuthored, kShuffled, kFarToNear, kNearToFar };
/// The scene-file and command-line names of the orders.
const char* to_string(DrawOrder o);
/// Parses "authored", "shuffled", "far-to-near" or "near-to-far"; false otherwise.
bool parse_draw_order(const std::string& s, DrawOrder& out);
enum class Shading { kSmooth, kFlat, kUnlit };

struct ObjectSpec {
  std::string name;  ///< for messages: "object[i]" or its `name`
  ObjectKind kind = ObjectKind::kMesh;
  std::string mesh;     ///< resolved path of the mesh / point file
  std::string texture;  ///< resolved path of an RGBA image over the object ("" = none)
  OpacitySource opacity_source = OpacitySource::kConstant;
  float opacity = 1.0f;  ///< alpha when constant
  ColorSource color_source = ColorSource::kConstant;
  std::array<float, 3> color{1.0f, 1.0f, 1.0f};  ///< linear RGB when constant
  DrawOrder order = DrawOrder::kAuthored;
  bool back_faces = true;  ///< keep back-facing triangles
  Shading shading = Shading::kSmooth;
  double scale = 1.0;        ///< uniform scale, applied first
  Vec3d rotate{0, 0, 0};     ///< degrees about x, then y, then z
  Vec3d translate{0, 0, 0};  ///< world units, applied last
  double size = 1.0;         ///< billboards: side length in world units
  uint32_t max_points = 0;   ///< billboards: 0 = every point, else an even subsample
};

struct CameraSpec {
  Vec3d eye{0, 0, 5}, target{0, 0, 0}, up{0, 1, 0};
  double fov_y = 45.0;             ///< vertical field of view, degrees
  double near = 0.1, far = 100.0;  ///< clip distances along the view direction, world units
};

struct LightSpec {
  bool headlight = true;     ///< light travels along the view direction
  Vec3d direction{0, 0, 1};  ///< towards the light, world space (when not headlight)
  double ambient = 0.15;     ///< fraction of the colour lit regardless of the normal
};

struct SceneSpec {
  std::string path;  ///< the scene file
  std::string name;
  uint32_t width = 640, height = 480;
  int spp = 16;
  uint64_t seed = 1;  ///< seed of the triangle shuffles
  DepthMode depth_mode = DepthMode::kPlane;
  ColorFormat color_format = ColorFormat::kRgbF32;
  Compression compression = Compression::kZstd;
  bool checksum = true;  ///< checksummed payload blocks (`capture --no-checksum`: false)
  std::array<float, 3> background{0.0f, 0.0f, 0.0f};
  CameraSpec camera;
  LightSpec light;
  std::vector<ObjectSpec> objects;
};

/// Command-line overrides of a scene file's values.
struct SceneOverrides {
  std::optional<std::string> mesh_dir;  ///< searched before the file's mesh_dir (else $ROPSIM_MESH_DIR)
  std::optional<int> spp;
  std::optional<uint32_t> width, height;
  std::optional<uint64_t> seed;
  std::optional<DrawOrder> order;  ///< every object's draw order
};

/// Reads and validates a scene file. Throws CaptureError.
SceneSpec load_scene_file(const std::string& path, const SceneOverrides& o = {});
/// The same from text; `path` names the file in messages and anchors relative paths.
SceneSpec parse_scene_text(const std::string& text, const std::string& path, const SceneOverrides& o = {});

}  // namespace ropsim
