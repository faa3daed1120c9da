#include "traces/capture/scene_file.h"

#include <toml++/toml.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "traces/capture/toml_keys.h"
#include "traces/format/utf8.h"
#include "util/toml_guard.h"

namespace ropsim {

namespace fs = std::filesystem;

namespace {

using TomlKeys = detail::TomlKeys<CaptureError>;

double norm(const Vec3d& v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

Vec3d cross(const Vec3d& a, const Vec3d& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

}  // namespace

SceneSpec parse_scene_text(const std::string& text, const std::string& path, const SceneOverrides& o) {
  const TomlInput in = toml_input(text, path);
  if (!in.error.empty()) throw CaptureError(in.error);
  toml::table root;
  try {
    root = toml::parse(in.ascii, path);
  } catch (const toml::parse_error& e) {
    throw CaptureError(path + ":" + std::to_string(e.source().begin.line) + ": " + std::string(e.description()));
  }
  SceneSpec s;
  s.path = path;
  TomlKeys k(root, path, "");
  s.name = k.string("name").value_or(fs::path(path).stem().string());
  if (!is_valid_utf8(s.name))  // a TOML string is UTF-8: the file name is not
    throw CaptureError(path + ": the file name is not valid UTF-8: give the scene a name (name = \"...\")");
  if (auto w = k.integer("width")) {
    if (*w < 1 || *w > kMaxScreenSide) k.fail(k.node("width"), "width", "must be in 1 .. 32768 pixels");
    s.width = uint32_t(*w);
  }
  if (auto h = k.integer("height")) {
    if (*h < 1 || *h > kMaxScreenSide) k.fail(k.node("height"), "height", "must be in 1 .. 32768 pixels");
    s.height = uint32_t(*h);
  }
  if (auto spp = k.integer("spp")) {
    if (*spp != 1 && *spp != 2 && *spp != 4 && *spp != 8 && *spp != 16 && *spp != 32 && *spp != 64)
      k.fail(k.node("spp"), "spp", "must be one of 1, 2, 4, 8, 16, 32, 64");
    s.spp = int(*spp);
  }
  if (auto seed = k.integer("seed")) {
    if (*seed < 0) k.fail(k.node("seed"), "seed", "must be >= 0");
    s.seed = uint64_t(*seed);
  }
  s.depth_mode =
      k.choice("depth", "plane", {"plane", "per-sample"}) == "plane" ? DepthMode::kPlane : DepthMode::kPerSample;
  s.color_format = k.choice("color_format", "rgb-f32", {"rgb-f32", "rgb-unorm8"}) == "rgb-f32"
                       ? ColorFormat::kRgbF32
                       : ColorFormat::kRgbUnorm8;
  s.compression = k.choice("compression", "zstd", {"zstd", "none"}) == "zstd" ? Compression::kZstd : Compression::kNone;
  if (auto bg = k.rgb("background")) s.background = *bg;

  // Mesh paths: looked up in the override folder (--mesh-dir, else
  // $ROPSIM_MESH_DIR) first, then in mesh_dir (relative to the scene file's folder).
  const fs::path scene_dir = fs::absolute(fs::path(path)).parent_path();
  fs::path mesh_dir = scene_dir;
  if (auto md = k.string("mesh_dir")) mesh_dir = scene_dir / *md;
  std::optional<fs::path> override_dir;
  if (const char* env = std::getenv("ROPSIM_MESH_DIR"); env && *env) override_dir = fs::path(env);
  if (o.mesh_dir) override_dir = fs::path(*o.mesh_dir);
  auto resolve_mesh = [&](const std::string& m) {
    std::error_code ec;
    if (override_dir && fs::exists(*override_dir / m, ec)) return (*override_dir / m).lexically_normal().string();
    if (fs::exists(mesh_dir / m, ec) || !override_dir) return (mesh_dir / m).lexically_normal().string();
    return (*override_dir / m).lexically_normal().string();  // missing everywhere: name the folder asked for
  };

  // camera
  const toml::table* cam = k.table("camera");
  if (!cam) k.fail(nullptr, "camera", "missing: give [camera] with eye, target, fov_y, near, far");
  {
    TomlKeys c(*cam, path, "camera.");
    auto eye = c.vec3("eye"), target = c.vec3("target");
    if (!eye) c.fail(nullptr, "eye", "missing");
    if (!target) c.fail(nullptr, "target", "missing");
    s.camera.eye = *eye;
    s.camera.target = *target;
    s.camera.up = c.vec3("up").value_or(Vec3d{0, 1, 0});
    s.camera.fov_y = c.number_in("fov_y", 45.0, 1e-3, 179.0, "(0, 180) degrees");
    s.camera.near = c.number_in("near", 0.1, 1e-9, 1e30, "(0, far) world units");
    s.camera.far = c.number_in("far", 100.0, 1e-9, 1e30, "(near, inf) world units");
    if (!(s.camera.far > s.camera.near)) c.fail(c.node("far"), "far", "must be greater than near");
    const Vec3d dir{s.camera.target[0] - s.camera.eye[0], s.camera.target[1] - s.camera.eye[1],
                    s.camera.target[2] - s.camera.eye[2]};
    if (norm(dir) == 0) c.fail(c.node("target"), "target", "equals eye: no view direction");
    if (norm(cross(dir, s.camera.up)) < 1e-9 * norm(dir) * norm(s.camera.up))
      c.fail(c.node("up"), "up", "is parallel to the view direction (or zero)");
    c.finish();
  }
  // light
  if (const toml::table* lt = k.table("light")) {
    TomlKeys l(*lt, path, "light.");
    if (auto d = l.vec3("direction")) {
      if (norm(*d) == 0) l.fail(l.node("direction"), "direction", "must not be zero");
      s.light.headlight = false;
      s.light.direction = *d;
    }
    s.light.ambient = l.number_in("ambient", s.light.ambient, 0.0, 1.0, "[0, 1]");
    l.finish();
  }
  // objects
  const toml::node* objs = k.node("object");
  if (!objs) k.fail(nullptr, "object", "the scene has no objects: add at least one [[object]] with a mesh");
  const toml::array* arr = objs->as_array();
  if (!arr || !arr->is_array_of_tables()) k.fail(objs, "object", "must be an array of tables ([[object]])");
  if (arr->empty()) k.fail(objs, "object", "the scene has no objects: add at least one [[object]] with a mesh");
  for (size_t i = 0; i < arr->size(); ++i) {
    const toml::table& t = *arr->get(i)->as_table();
    const std::string pre = "object[" + std::to_string(i) + "].";
    TomlKeys ok(t, path, pre);
    ObjectSpec ob;
    ob.name = ok.string("name").value_or("object[" + std::to_string(i) + "]");
    ob.kind = ok.choice("type", "mesh", {"mesh", "billboards"}) == "mesh" ? ObjectKind::kMesh : ObjectKind::kBillboards;
    auto mesh = ok.string(ob.kind == ObjectKind::kMesh ? "mesh" : "points");
    if (!mesh) ok.fail(nullptr, ob.kind == ObjectKind::kMesh ? "mesh" : "points", "missing: the mesh file");
    ob.mesh = resolve_mesh(*mesh);
    if (auto tex = ok.string("texture")) ob.texture = (scene_dir / *tex).lexically_normal().string();
    if (const toml::node* op = ok.node("opacity")) {
      if (op->is_string()) {
        if (*op->value<std::string>() != "material")
          ok.fail(op, "opacity", "must be a number in [0, 1] or \"material\"");
        ob.opacity_source = OpacitySource::kMaterial;
      } else {
        ob.opacity = float(ok.number_in("opacity", 1.0, 0.0, 1.0, "[0, 1] (or \"material\")"));
      }
    }
    if (const toml::node* c = ok.node("color")) {
      if (c->is_string()) {
        const std::string v = *c->value<std::string>();
        if (v == "material")
          ob.color_source = ColorSource::kMaterial;
        else if (v == "vertex")
          ob.color_source = ColorSource::kVertex;
        else
          ok.fail(c, "color", "must be [r, g, b], \"material\" or \"vertex\"");
      } else {
        ob.color = *ok.rgb("color");
      }
    }
    parse_draw_order(ok.choice("order", "authored", {"authored", "shuffled", "far-to-near", "near-to-far"}), ob.order);
    const std::string sh = ok.choice("shading", "smooth", {"smooth", "flat", "unlit"});
    ob.shading = sh == "smooth" ? Shading::kSmooth : sh == "flat" ? Shading::kFlat : Shading::kUnlit;
    // Default: back faces kept unless the object is opaque (constant opacity 1).
    const bool opaque = ob.opacity_source == OpacitySource::kConstant && ob.opacity >= 1.0f;
    ob.back_faces = ok.boolean("back_faces").value_or(!opaque);
    ob.scale = ok.number_in("scale", 1.0, 1e-30, 1e30, "(0, inf)");
    ob.rotate = ok.vec3("rotate").value_or(Vec3d{0, 0, 0});
    ob.translate = ok.vec3("translate").value_or(Vec3d{0, 0, 0});
    if (ob.kind == ObjectKind::kBillboards) {
      ob.size = ok.number_in("size", 1.0, 1e-30, 1e30, "(0, inf) world units");
      if (auto mp = ok.integer("max_points")) {
        if (*mp < 0 || *mp > 100000000) ok.fail(ok.node("max_points"), "max_points", "must be in 0 .. 1e8 (0 = all)");
        ob.max_points = uint32_t(*mp);
      }
    }
    ok.finish();
    s.objects.push_back(ob);
  }
  k.finish();

  if (o.spp) s.spp = *o.spp;
  if (o.width) s.width = *o.width;
  if (o.height) s.height = *o.height;
  if (o.seed) s.seed = *o.seed;
  if (o.order)
    for (auto& ob : s.objects) ob.order = *o.order;
  return s;
}

const char* to_string(DrawOrder o) {
  switch (o) {
    case DrawOrder::kAuthored:
      return "authored";
    case DrawOrder::kShuffled:
      return "shuffled";
    case DrawOrder::kFarToNear:
      return "far-to-near";
    case DrawOrder::kNearToFar:
      return "near-to-far";
  }
  return "?";
}

bool parse_draw_order(const std::string& s, DrawOrder& out) {
  for (DrawOrder o : {DrawOrder::kAuthored, DrawOrder::kShuffled, DrawOrder::kFarToNear, DrawOrder::kNearToFar})
    if (s == to_string(o)) {
      out = o;
      return true;
    }
  return false;
}

SceneSpec load_scene_file(const std::string& path, const SceneOverrides& o) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw CaptureError(path + ": no such scene file");
  std::ifstream f(path, std::ios::binary);
  std::ostringstream ss;
  ss << f.rdbuf();
  if (!f && !f.eof()) throw CaptureError(path + ": cannot read the scene file");
  return parse_scene_text(ss.str(), path, o);
}

}  // namespace ropsim
