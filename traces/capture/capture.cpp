#include "traces/capture/capture.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "rtl_models/algo/random_hash.h"
#include "traces/capture/mesh_loader.h"
#include "traces/raster/sample_patterns.h"

namespace ropsim {

namespace {

constexpr double kPi = 3.14159265358979323846;

Vec3d sub(const Vec3d& a, const Vec3d& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot(const Vec3d& a, const Vec3d& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3d cross(const Vec3d& a, const Vec3d& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
Vec3d normalize(const Vec3d& v) {
  const double l = std::sqrt(dot(v, v));
  return l > 0 ? Vec3d{v[0] / l, v[1] / l, v[2] / l} : Vec3d{0, 0, 0};
}

/// Object transform: scale, rotate about x, y, z (degrees), translate.
struct ObjectTransform {
  double m[3][3];
  Vec3d t;
  explicit ObjectTransform(const ObjectSpec& o) : t(o.translate) {
    const double ax = o.rotate[0] * kPi / 180, ay = o.rotate[1] * kPi / 180, az = o.rotate[2] * kPi / 180;
    const double cx = std::cos(ax), sx = std::sin(ax), cy = std::cos(ay), sy = std::sin(ay), cz = std::cos(az),
                 sz = std::sin(az);
    // R = Rz * Ry * Rx
    const double r[3][3] = {{cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx},
                            {sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx},
                            {-sy, cy * sx, cy * cx}};
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) m[i][j] = r[i][j];
    scale = o.scale;
  }
  double scale = 1;
  Vec3d point(const std::array<double, 3>& p) const {
    Vec3d q{};
    for (int i = 0; i < 3; ++i) q[i] = scale * (m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2]) + t[i];
    return q;
  }
  Vec3d normal(const std::array<double, 3>& n) const {  // rotation only (uniform scale)
    Vec3d q{};
    for (int i = 0; i < 3; ++i) q[i] = m[i][0] * n[0] + m[i][1] * n[1] + m[i][2] * n[2];
    return q;
  }
};

/// Look-at view and a perspective projection with depth 0 at near, 1 at far.
struct Camera {
  Vec3d eye, s, u, f;
  double sx, sy, a, b;  // x_c = sx*xv, y_c = sy*yv, z_c = a*d + b, w_c = d
  Camera(const CameraSpec& c, uint32_t width, uint32_t height) : eye(c.eye) {
    f = normalize(sub(c.target, c.eye));
    s = normalize(cross(f, c.up));
    u = cross(s, f);
    const double t = 1.0 / std::tan(c.fov_y * kPi / 360.0);
    sy = t;
    sx = t * double(height) / double(width);
    a = c.far / (c.far - c.near);
    b = -c.far * c.near / (c.far - c.near);
  }
  std::array<float, 4> clip(const Vec3d& p) const {
    const Vec3d q = sub(p, eye);
    const double xv = dot(q, s), yv = dot(q, u), d = dot(q, f);
    return {float(sx * xv), float(sy * yv), float(a * d + b), float(d)};
  }
};

class ShuffleRng {
 public:
  explicit ShuffleRng(uint64_t seed) : state_(mix64(seed ^ 0xC0FFEE5EEDull)) {}
  uint64_t below(uint64_t n) { return static_cast<uint64_t>((mix64(state_++) >> 11) * 0x1p-53 * double(n)); }

 private:
  uint64_t state_;
};

template <class T>
void shuffle(std::vector<T>& v, uint64_t seed) {
  ShuffleRng r(seed);
  for (size_t i = v.size(); i > 1; --i) std::swap(v[i - 1], v[std::min<size_t>(size_t(r.below(i)), i - 1)]);
}

float shade(const ObjectSpec& ob, const LightSpec& light, const Vec3d& l, const Vec3d& n) {
  if (ob.shading == Shading::kUnlit) return 1.0f;
  const double nl = std::abs(dot(n, l));  // two-sided: back faces are lit like front faces
  return float(light.ambient + (1.0 - light.ambient) * nl);
}

PreparedDraw prepare_mesh(const SceneSpec& s, size_t index, const Camera& cam, const Vec3d& l) {
  const ObjectSpec& ob = s.objects[index];
  const bool material_textures = ob.texture.empty() && (ob.color_source == ColorSource::kMaterial ||
                                                        ob.opacity_source == OpacitySource::kMaterial);
  LoadedMesh mesh = load_mesh(ob.mesh, false, material_textures);
  const std::string where = s.path + ": " + ob.name + ": ";
  if (ob.color_source == ColorSource::kVertex && mesh.colors.empty())
    throw CaptureError(where + "color = \"vertex\" but " + ob.mesh + " has no vertex colours");
  if (!ob.texture.empty() && mesh.uvs.empty())
    throw CaptureError(where + "texture = " + ob.texture + " but " + ob.mesh + " has no texture coordinates");
  const ObjectTransform xf(ob);
  std::vector<Vec3d> wpos(mesh.positions.size());
  std::vector<std::array<float, 4>> clip(mesh.positions.size());
  for (size_t i = 0; i < wpos.size(); ++i) {
    wpos[i] = xf.point(mesh.positions[i]);
    clip[i] = cam.clip(wpos[i]);
  }
  PreparedDraw d;
  d.name = ob.name;
  d.back_faces = ob.back_faces;
  if (!ob.texture.empty())
    d.textures.push_back(load_texture_file(ob.texture));
  else if (!mesh.uvs.empty())
    d.textures = std::move(mesh.textures);
  std::vector<size_t> order(mesh.triangles.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  if (ob.order == DrawOrder::kShuffled) shuffle(order, s.seed ^ (uint64_t(index) * 0x9E3779B97F4A7C15ull));
  if (ob.order == DrawOrder::kFarToNear || ob.order == DrawOrder::kNearToFar) {
    // By the view depth (clip w) of the centroid; ties keep the file's order.
    std::vector<double> depth(mesh.triangles.size());
    for (size_t i = 0; i < depth.size(); ++i)
      for (int k = 0; k < 3; ++k) depth[i] += double(clip[mesh.triangles[i][size_t(k)]][3]);
    const bool far_first = ob.order == DrawOrder::kFarToNear;
    std::stable_sort(order.begin(), order.end(),
                     [&](size_t a, size_t b) { return far_first ? depth[a] > depth[b] : depth[a] < depth[b]; });
  }
  d.triangles.reserve(order.size());
  for (size_t ti : order) {
    const auto& tri = mesh.triangles[ti];
    const MeshMaterial& mat = mesh.materials[mesh.triangle_material[ti]];
    ClipTriangle ct;
    ct.prim_id = uint32_t(d.triangles.size());
    if (!ob.texture.empty()) {
      ct.texture = 0;
      ct.tex_rgb = ct.tex_alpha = true;
    } else if (mat.texture >= 0 && !mesh.uvs.empty()) {
      ct.texture = mat.texture;
      ct.tex_rgb = ob.color_source == ColorSource::kMaterial;
      ct.tex_alpha = ob.opacity_source == OpacitySource::kMaterial && mat.alpha_mode != AlphaMode::kOpaque;
    }
    if (!ct.tex_rgb && !ct.tex_alpha) ct.texture = -1;
    // Texture coordinates shifted by whole periods (repeat wrap) to be >= 0.
    double du = 0, dv = 0;
    if (ct.texture >= 0) {
      du = -std::floor(std::min({mesh.uvs[tri[0]][0], mesh.uvs[tri[1]][0], mesh.uvs[tri[2]][0]}));
      dv = -std::floor(std::min({mesh.uvs[tri[0]][1], mesh.uvs[tri[1]][1], mesh.uvs[tri[2]][1]}));
    }
    const Vec3d fn = normalize(cross(sub(wpos[tri[1]], wpos[tri[0]]), sub(wpos[tri[2]], wpos[tri[0]])));
    for (int k = 0; k < 3; ++k) {
      const uint32_t vi = tri[size_t(k)];
      ClipVertex& cv = ct.v[size_t(k)];
      cv.pos = clip[vi];
      std::array<float, 3> base = ob.color;
      float alpha = ob.opacity;
      if (ob.color_source == ColorSource::kMaterial) base = {mat.base[0], mat.base[1], mat.base[2]};
      if (ob.color_source == ColorSource::kVertex) base = {mesh.colors[vi][0], mesh.colors[vi][1], mesh.colors[vi][2]};
      if (ob.opacity_source == OpacitySource::kMaterial) {
        alpha = mat.alpha_mode == AlphaMode::kBlend ? mat.base[3] : 1.0f;
        if (mat.alpha_mode == AlphaMode::kBlend && !mesh.colors.empty()) alpha *= mesh.colors[vi][3];
        if (mat.alpha_mode == AlphaMode::kMask) {
          if (ct.tex_alpha) {  // per fragment: base alpha x texel alpha against the cutoff
            alpha = mat.base[3];
            ct.mask = true;
            ct.cutoff = mat.alpha_cutoff;
          } else if (mat.base[3] < mat.alpha_cutoff) {
            ct.discarded = true;
          }
        }
      }
      Vec3d n = fn;
      if (ob.shading == Shading::kSmooth) {
        const Vec3d vn = normalize(xf.normal(mesh.normals[vi]));
        if (dot(vn, vn) > 0) n = vn;
      }
      const float sh = shade(ob, s.light, l, n);
      if (ct.texture >= 0) {
        ct.tint = base;
        cv.rgb = {float(mesh.uvs[vi][0] + du), float(mesh.uvs[vi][1] + dv), sh};
      } else {
        for (int c = 0; c < 3; ++c) cv.rgb[size_t(c)] = std::max(0.0f, base[size_t(c)] * sh);
      }
      cv.alpha = std::clamp(alpha, 0.0f, 1.0f);
    }
    d.triangles.push_back(ct);
  }
  return d;
}

PreparedDraw prepare_billboards(const SceneSpec& s, size_t index, const Camera& cam) {
  const ObjectSpec& ob = s.objects[index];
  const LoadedMesh mesh = load_mesh(ob.mesh, /*points_ok=*/true);
  std::vector<uint32_t> pts = mesh.points;
  if (pts.empty())  // a triangle mesh: use its vertices
    for (uint32_t i = 0; i < mesh.positions.size(); ++i) pts.push_back(i);
  if (ob.color_source == ColorSource::kVertex && mesh.colors.empty())
    throw CaptureError(s.path + ": " + ob.name + ": color = \"vertex\" but " + ob.mesh + " has no vertex colours");
  if (ob.max_points && ob.max_points < pts.size()) {  // an even subsample, in file order
    std::vector<uint32_t> sub;
    for (uint64_t i = 0; i < ob.max_points; ++i) sub.push_back(pts[size_t(i * pts.size() / ob.max_points)]);
    pts.swap(sub);
  }
  if (ob.order == DrawOrder::kShuffled) shuffle(pts, s.seed ^ (uint64_t(index) * 0x9E3779B97F4A7C15ull));
  const ObjectTransform xf(ob);
  if (ob.order == DrawOrder::kFarToNear || ob.order == DrawOrder::kNearToFar) {
    // By the view depth (clip w) of each point; ties keep the file's order.
    std::vector<std::pair<double, uint32_t>> by;
    for (uint32_t pi : pts) by.emplace_back(double(cam.clip(xf.point(mesh.positions[pi]))[3]), pi);
    const bool far_first = ob.order == DrawOrder::kFarToNear;
    std::stable_sort(by.begin(), by.end(),
                     [&](const auto& a, const auto& b) { return far_first ? a.first > b.first : a.first < b.first; });
    for (size_t i = 0; i < by.size(); ++i) pts[i] = by[i].second;
  }
  const double h = ob.size / 2;
  const Vec3d R{cam.s[0] * h, cam.s[1] * h, cam.s[2] * h}, U{cam.u[0] * h, cam.u[1] * h, cam.u[2] * h};
  PreparedDraw d;
  d.name = ob.name;
  d.back_faces = true;
  if (!ob.texture.empty()) d.textures.push_back(load_texture_file(ob.texture));
  d.triangles.reserve(pts.size() * 2);
  for (uint32_t pi : pts) {
    const Vec3d c = xf.point(mesh.positions[pi]);
    std::array<float, 3> rgb = ob.color;
    if (ob.color_source == ColorSource::kVertex) rgb = {mesh.colors[pi][0], mesh.colors[pi][1], mesh.colors[pi][2]};
    if (ob.color_source == ColorSource::kMaterial)
      rgb = {mesh.materials[0].base[0], mesh.materials[0].base[1], mesh.materials[0].base[2]};
    ClipVertex q[4];
    const double cx[4] = {-1, 1, 1, -1}, cy[4] = {-1, -1, 1, 1};
    for (int k = 0; k < 4; ++k) {
      q[k].pos = cam.clip(
          {c[0] + cx[k] * R[0] + cy[k] * U[0], c[1] + cx[k] * R[1] + cy[k] * U[1], c[2] + cx[k] * R[2] + cy[k] * U[2]});
      q[k].rgb = d.textures.empty() ? rgb : std::array<float, 3>{float(cx[k] + 1) / 2, float(cy[k] + 1) / 2, 1.0f};
      q[k].alpha = ob.opacity;
    }
    ClipTriangle t;
    if (!d.textures.empty()) {
      t.texture = 0;
      t.tint = rgb;
      t.tex_rgb = t.tex_alpha = true;
    }
    t.prim_id = uint32_t(d.triangles.size());
    t.v = {q[0], q[1], q[2]};
    d.triangles.push_back(t);
    t.prim_id = uint32_t(d.triangles.size());
    t.v = {q[0], q[2], q[3]};
    d.triangles.push_back(t);
  }
  return d;
}

/// Sutherland-Hodgman in homogeneous clip space against the plane dist(v) >= 0.
struct HVert {
  double p[4];
  double rgb[3];
  double a;
};

template <class Dist>
int clip_polygon(const HVert* in, int n, HVert* out, Dist dist) {
  int m = 0;
  for (int i = 0; i < n; ++i) {
    const HVert& A = in[i];
    const HVert& B = in[(i + 1) % n];
    const double da = dist(A), db = dist(B);
    if (da >= 0) out[m++] = A;
    if ((da >= 0) != (db >= 0)) {
      // Always from the inside vertex to the outside one, so that the two
      // triangles sharing an edge get bit-identical new vertices (watertight).
      const HVert& I = da >= 0 ? A : B;
      const HVert& O = da >= 0 ? B : A;
      const double di = da >= 0 ? da : db, dout = da >= 0 ? db : da;
      const double t = di / (di - dout);
      HVert c;
      for (int k = 0; k < 4; ++k) c.p[k] = I.p[k] + t * (O.p[k] - I.p[k]);
      for (int k = 0; k < 3; ++k) c.rgb[k] = I.rgb[k] + t * (O.rgb[k] - I.rgb[k]);
      c.a = I.a + t * (O.a - I.a);
      out[m++] = c;
    }
  }
  return m;
}

}  // namespace

uint64_t PreparedScene::triangles() const {
  uint64_t n = 0;
  for (const auto& d : draws) n += d.triangles.size();
  return n;
}

PreparedScene prepare_scene(const SceneSpec& spec) {
  PreparedScene ps;
  ps.spec = spec;
  const Camera cam(spec.camera, spec.width, spec.height);
  const Vec3d l = spec.light.headlight ? Vec3d{-cam.f[0], -cam.f[1], -cam.f[2]} : normalize(spec.light.direction);
  for (size_t i = 0; i < spec.objects.size(); ++i) {
    try {
      ps.draws.push_back(spec.objects[i].kind == ObjectKind::kMesh ? prepare_mesh(spec, i, cam, l)
                                                                   : prepare_billboards(spec, i, cam));
    } catch (const CaptureError& e) {
      const std::string msg = e.what();
      if (msg.rfind(spec.path + ":", 0) == 0) throw;
      throw CaptureError(spec.path + ": " + spec.objects[i].name + ": " + msg);
    }
  }
  return ps;
}

TraceHeader capture_header(const SceneSpec& spec) {
  TraceHeader h;
  h.width = spec.width;
  h.height = spec.height;
  h.spp = spec.spp;
  h.depth_mode = spec.depth_mode;
  h.color_format = spec.color_format;
  h.compression = spec.compression;
  h.checksummed = spec.checksum;
  h.clear_color = spec.background;
  h.clear_depth = 1.0f;
  h.positions = standard_sample_positions(spec.spp);
  h.scene_name = spec.name;
  return h;
}

CaptureStats rasterize_prepared(const PreparedScene& ps, const TraceHeader& h,
                                const std::function<void(const Fragment&)>& emit,
                                const std::function<void(uint64_t, uint64_t)>& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  CaptureStats st;
  Rasterizer rast(h);
  // Guard band: keep screen coordinates within +-2^20 pixels so that the
  // 8-bit sub-pixel edge functions stay far from int64 overflow.
  const double g = std::ldexp(1.0, 21) / double(std::max(h.width, h.height));
  const float hw = float(h.width) * 0.5f, hh = float(h.height) * 0.5f;
  const uint64_t total = ps.triangles();
  uint64_t done = 0, next_report = 0;
  std::vector<Fragment> pieces;  // fragments of a triangle split by clipping, merged per pixel
  const auto emit_counted = [&](const Fragment& f) {
    ++st.fragments;
    st.covered_samples += uint64_t(__builtin_popcountll(f.coverage));
    emit(f);
  };
  if (progress) progress(0, total);
  for (uint32_t di = 0; di < ps.draws.size(); ++di) {
    const PreparedDraw& d = ps.draws[di];
    for (const ClipTriangle& ct : d.triangles) {
      ++st.triangles;
      if (progress && ++done >= next_report) {
        progress(done, total);
        next_report = done + std::max<uint64_t>(1, total / 200);
      }
      if (ct.discarded) {
        ++st.discarded;
        continue;
      }
      HVert a[16], b[16];
      for (int k = 0; k < 3; ++k) {
        const ClipVertex& v = ct.v[size_t(k)];
        for (int c = 0; c < 4; ++c) a[k].p[c] = v.pos[size_t(c)];
        for (int c = 0; c < 3; ++c) a[k].rgb[c] = v.rgb[size_t(c)];
        a[k].a = v.alpha;
      }
      // Outcodes: trivially outside / inside.
      auto planes = [&](const HVert& v, int i) {
        switch (i) {
          case 0:
            return v.p[2];  // near: z >= 0
          case 1:
            return v.p[3] - v.p[2];  // far: z <= w
          case 2:
            return g * v.p[3] - v.p[0];  // guard band x <= g w
          case 3:
            return g * v.p[3] + v.p[0];
          case 4:
            return g * v.p[3] - v.p[1];
          default:
            return g * v.p[3] + v.p[1];
        }
      };
      unsigned out_all = 0x3F, out_any = 0;
      for (int k = 0; k < 3; ++k) {
        unsigned code = 0;
        for (int i = 0; i < 6; ++i)
          if (!(planes(a[k], i) >= 0)) code |= 1u << i;
        out_all &= code;
        out_any |= code;
      }
      if (out_all) {
        ++st.outside;
        continue;
      }
      int n = 3;
      HVert* poly = a;
      if (out_any) {
        ++st.clipped;
        HVert* src = a;
        HVert* dst = b;
        for (int i = 0; i < 6 && n >= 3; ++i) {
          if (!(out_any >> i & 1)) continue;
          n = clip_polygon(src, n, dst, [&](const HVert& v) { return planes(v, i); });
          std::swap(src, dst);
        }
        poly = src;
        if (n < 3) {
          ++st.outside;
          continue;
        }
      }
      // Perspective divide and viewport (y down, depth 0..1), in binary32 as
      // GPUs and Mesa do, so that snapping to 1/256 pixel rounds the same values.
      ScreenVertex sv[16];
      for (int k = 0; k < n; ++k) {
        const float iw = 1.0f / float(poly[k].p[3]);
        sv[k].x = double(float(poly[k].p[0]) * iw * hw + hw);
        sv[k].y = double(-(float(poly[k].p[1]) * iw) * hh + hh);
        sv[k].z = double(float(poly[k].p[2]) * iw);
        sv[k].inv_w = 1.0 / poly[k].p[3];
        for (int c = 0; c < 3; ++c) sv[k].rgb[size_t(c)] = float(poly[k].rgb[c]);
        sv[k].alpha = float(poly[k].a);
      }
      if (!d.back_faces) {
        // Front faces are counter-clockwise in GL's y-up window space, i.e.
        // negative signed area in this y-down screen space.
        double area = 0;
        for (int k = 0; k < n; ++k) {
          const int j = (k + 1) % n;
          area += sv[k].x * sv[j].y - sv[j].x * sv[k].y;
        }
        if (area >= 0) {
          ++st.back_facing;
          continue;
        }
      }
      const std::function<void(const Fragment&)> emit_tri = [&](const Fragment& in) {
        if (ct.texture < 0) return emit_counted(in);
        Fragment f = in;
        const std::array<float, 4> tx = d.textures[size_t(ct.texture)].sample(in.rgb[0], in.rgb[1]);
        for (int c = 0; c < 3; ++c)
          f.rgb[size_t(c)] = ct.tint[size_t(c)] * in.rgb[2] * (ct.tex_rgb ? tx[size_t(c)] : 1.0f);
        float a = in.alpha * (ct.tex_alpha ? tx[3] : 1.0f);
        if (ct.mask) {
          if (a < ct.cutoff) {
            ++st.discarded_fragments;
            return;
          }
          a = 1.0f;
        }
        f.alpha = std::clamp(a, 0.0f, 1.0f);
        emit_counted(f);
      };
      ScreenTriangle t;
      t.draw_id = di;
      t.prim_id = ct.prim_id;
      t.perspective = true;
      t.depth_from_unsnapped = true;
      const uint64_t before = rast.stats().culled_degenerate;
      if (n == 3) {
        t.v = {sv[0], sv[1], sv[2]};
        rast.rasterize(t, emit_tri);
      } else {
        // A clipped polygon is one primitive: rasterize its fan and merge the
        // pieces' coverage per pixel (the top-left rule keeps them disjoint).
        pieces.clear();
        for (int k = 1; k + 1 < n; ++k) {
          t.v = {sv[0], sv[k], sv[k + 1]};
          rast.rasterize(t, [&](const Fragment& f) { pieces.push_back(f); });
        }
        std::stable_sort(pieces.begin(), pieces.end(),
                         [](const Fragment& p, const Fragment& q) { return p.y != q.y ? p.y < q.y : p.x < q.x; });
        for (size_t i = 0; i < pieces.size();) {
          Fragment f = pieces[i];
          size_t j = i + 1;
          for (; j < pieces.size() && pieces[j].x == f.x && pieces[j].y == f.y; ++j) {
            f.coverage |= pieces[j].coverage;
            for (int s = 0; s < h.spp; ++s)
              if (pieces[j].coverage >> s & 1) f.z[size_t(s)] = pieces[j].z[size_t(s)];
          }
          emit_tri(f);
          i = j;
        }
      }
      if (rast.stats().culled_degenerate != before && n == 3) ++st.degenerate;
    }
  }
  if (progress) progress(total, total);
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return st;
}

CaptureStats capture_to_file(const SceneSpec& spec, const std::string& out_path, bool allow_empty,
                             const std::function<void(uint64_t, uint64_t)>& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  PreparedScene ps = prepare_scene(spec);
  const TraceHeader h = capture_header(spec);
  TraceWriter w(out_path, h);
  CaptureStats st = rasterize_prepared(
      ps, h, [&](const Fragment& f) { w.write(f); }, progress);
  if (st.fragments == 0 && !allow_empty)
    throw CaptureError(spec.path + ": nothing visible: " + std::to_string(st.triangles) + " triangles, " +
                       std::to_string(st.outside) + " outside the view frustum, " + std::to_string(st.back_facing) +
                       " back-facing, " + std::to_string(st.degenerate) +
                       " too small; check [camera] (or pass --allow-empty)");
  w.finish();
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return st;
}

}  // namespace ropsim
