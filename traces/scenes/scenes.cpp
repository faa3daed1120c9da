#include "traces/scenes/scenes.h"

#include <algorithm>
#include <cmath>

#include "rtl_models/algo/numerics.h"
#include "rtl_models/algo/random_hash.h"
#include "traces/raster/sample_patterns.h"

namespace ropsim {

namespace {

constexpr double kPi = 3.14159265358979323846;

/// Platform-independent generator for scene construction (std distributions
/// are implementation-defined, so they are not used).
class SceneRng {
 public:
  explicit SceneRng(uint64_t seed) : state_(mix64(seed ^ 0x5CE7E5EEDull)) {}
  double uniform() { return static_cast<double>(mix64(state_++) >> 11) * 0x1p-53; }
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  double normal() {  // Box-Muller
    double u1 = std::max(uniform(), 1e-300), u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
  }
  template <class T>
  void shuffle(std::vector<T>& v) {
    for (size_t i = v.size(); i > 1; --i) std::swap(v[i - 1], v[static_cast<size_t>(uniform() * i)]);
  }

 private:
  uint64_t state_;
};

using Rgb = std::array<float, 3>;

ScreenVertex vert(double x, double y, double z, Rgb c, float a) {
  ScreenVertex v;
  v.x = x;
  v.y = y;
  v.z = z;
  v.rgb = c;
  v.alpha = a;
  return v;
}

/// A quad as two triangles (a, b, c) and (a, c, d), corners in order.
void add_quad(std::vector<ScreenTriangle>& out, uint32_t draw, const ScreenVertex& a, const ScreenVertex& b,
              const ScreenVertex& c, const ScreenVertex& d) {
  ScreenTriangle t;
  t.draw_id = draw;
  t.v = {a, b, c};
  out.push_back(t);
  t.v = {a, c, d};
  out.push_back(t);
}

/// An axis-aligned rectangle tessellated into nx x ny quads; alpha may ramp in x.
void add_rect(std::vector<ScreenTriangle>& out, uint32_t draw, double x0, double y0, double x1, double y1, double z,
              Rgb c, float a0, float a1, int nx = 1, int ny = 1) {
  auto at = [&](int i, int j) {
    double u = double(i) / nx, v = double(j) / ny;
    return vert(x0 + u * (x1 - x0), y0 + v * (y1 - y0), z, c, static_cast<float>(a0 + u * (a1 - a0)));
  };
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) add_quad(out, draw, at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
}

void number_primitives(std::vector<ScreenTriangle>& tris) {
  // gl_PrimitiveID semantics: the index of the triangle within its draw.
  uint32_t draw = ~0u, prim = 0;
  for (auto& t : tris) {
    if (t.draw_id != draw) {
      draw = t.draw_id;
      prim = 0;
    }
    t.prim_id = prim++;
  }
}

void testcard(Scene& s, SceneRng&) {
  const double W = s.header.width, H = s.header.height;
  const Rgb white{1, 1, 1};
  auto& t = s.triangles;
  const double band = H / 3.0, pad = band * 0.12;
  // Top: alpha ramp 0 -> 1 (one surface, 8 x 2 quads: interior edges).
  add_rect(t, 0, W * 0.05 + 0.3, pad + 0.5, W * 0.95 + 0.3, band - pad + 0.5, 0.5, white, 0.0f, 1.0f, 8, 2);
  // Middle: constant alpha 0.61, also tessellated so the surface has interior edges.
  add_rect(t, 1, W * 0.05 + 0.3, band + pad + 0.5, W * 0.95 + 0.3, 2 * band - pad + 0.5, 0.5, white, 0.61f, 0.61f, 8,
           2);
  // Bottom: five overlapping quads, alpha 0.75, at distinct depths, drawn back to front.
  const double qw = W * 0.3, step = (W * 0.9 - qw) / 4.0;
  for (int i = 0; i < 5; ++i) {
    double x0 = W * 0.05 + 0.3 + i * step;
    add_rect(t, 2 + i, x0, 2 * band + pad + 0.5, x0 + qw, 3 * band - pad + 0.5, 0.8 - 0.1 * i, white, 0.75f, 0.75f);
  }
}

void eight_layers(Scene& s, SceneRng& rng) {
  const double W = s.header.width, H = s.header.height;
  std::vector<int> order{0, 1, 2, 3, 4, 5, 6, 7};
  rng.shuffle(order);
  uint32_t draw = 0;
  for (int k : order) add_rect(s.triangles, draw++, 0, 0, W, H, 0.1 * (k + 1), Rgb{1, 1, 1}, 0.1f, 0.1f);
}

void enderton1(Scene& s, SceneRng&) {
  const double W = s.header.width, H = s.header.height;
  s.header.clear_color = {0, 0, 1};
  add_rect(s.triangles, 0, 0, 0, W, H, 0.6, Rgb{0, 1, 0}, 0.45f, 0.45f);  // green, far, drawn first
  add_rect(s.triangles, 1, 0, 0, W, H, 0.3, Rgb{1, 0, 0}, 0.45f, 0.45f);  // red, near
}

void enderton2(Scene& s, SceneRng&) {
  const double W = s.header.width, H = s.header.height;
  s.header.clear_color = {0.25f, 0.25f, 0.25f};
  for (int k = 0; k < 4; ++k) add_rect(s.triangles, k, 0, 0, W, H, 0.8 - 0.2 * k, Rgb{1, 1, 1}, 0.25f, 0.25f);
}

/// A folded sheet: x folds over itself ~3 times, y ~2 times, so most covered
/// pixels see 3-6 layers; colour cells like a printed fabric; two-sided
/// diffuse shading; triangles in random order (LK Figure 10 / Table 1).
void cloth(Scene& s, SceneRng& rng) {
  const double W = s.header.width, H = s.header.height;
  const int N = 14;
  auto pos = [&](double u, double v, double out[3]) {
    out[0] = W * (0.5 + 0.20 * (2 * u - 1) + 0.21 * std::sin(5 * kPi * u + 0.5 * v));
    out[1] = H * (0.5 + 0.34 * (2 * v - 1) + 0.11 * std::sin(3 * kPi * v + 0.6 * u));
    out[2] = 0.5 + 0.2 * std::cos(5 * kPi * u + 0.5 * v) + 0.12 * std::cos(3 * kPi * v) +
             0.04 * std::sin(5 * u + 3 * v) + 0.08 * (u - 0.5);
  };
  auto shade = [&](double u, double v) {
    const double e = 1e-3;
    double p[3], pu[3], pv[3];
    pos(u, v, p);
    pos(u + e, v, pu);
    pos(u, v + e, pv);
    double a[3] = {pu[0] - p[0], pu[1] - p[1], (pu[2] - p[2]) * W};
    double b[3] = {pv[0] - p[0], pv[1] - p[1], (pv[2] - p[2]) * W};
    double n[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) + 1e-30;
    const double l[3] = {0.37, -0.46, -0.81};
    double d = std::fabs((n[0] * l[0] + n[1] * l[1] + n[2] * l[2]) / len);
    return 0.3 + 0.7 * d;
  };
  static const Rgb palette[6] = {{0.90f, 0.20f, 0.15f}, {0.95f, 0.80f, 0.20f}, {0.20f, 0.45f, 0.90f},
                                 {0.25f, 0.75f, 0.35f}, {0.85f, 0.85f, 0.85f}, {0.60f, 0.25f, 0.70f}};
  std::vector<ScreenTriangle> tris;
  for (int j = 0; j < N; ++j)
    for (int i = 0; i < N; ++i) {
      const Rgb& base = palette[((i / 4) + 2 * (j / 4) + ((i + j) / 2) % 2) % 6];
      ScreenVertex c[4];
      const int di[4] = {0, 1, 1, 0}, dj[4] = {0, 0, 1, 1};
      for (int k = 0; k < 4; ++k) {
        double u = double(i + di[k]) / N, v = double(j + dj[k]) / N, p[3];
        pos(u, v, p);
        float sh = static_cast<float>(shade(u, v));
        c[k] = vert(p[0], p[1], p[2], Rgb{base[0] * sh, base[1] * sh, base[2] * sh}, 0.4f);
      }
      add_quad(tris, 0, c[0], c[1], c[2], c[3]);
    }
  rng.shuffle(tris);
  s.triangles = std::move(tris);
}

/// Dozens of overlapping camera-facing billboards with alpha 0.05, unsorted (LK Figure 8).
void smoke(Scene& s, SceneRng& rng) {
  const double W = s.header.width, H = s.header.height;
  s.header.clear_color = {0.05f, 0.07f, 0.12f};
  const int kBillboards = 96;
  for (int b = 0; b < kBillboards; ++b) {
    double cx = W * (0.5 + 0.12 * rng.normal()), cy = H * (0.55 + 0.11 * rng.normal());
    double r = W * rng.uniform(0.08, 0.2), ang = rng.uniform(0, 2 * kPi), z = rng.uniform(0.1, 0.9);
    float g = static_cast<float>(rng.uniform(0.55, 0.95));
    ScreenVertex c[4];
    for (int k = 0; k < 4; ++k) {
      double a = ang + k * kPi / 2;
      float tint = static_cast<float>(rng.uniform(0.8, 1.1));  // a coarse stand-in for a texture
      c[k] = vert(cx + r * std::cos(a), cy + r * std::sin(a), z,
                  Rgb{g * tint, g * tint, std::min(1.0f, g * tint * 1.05f)}, 0.05f);
    }
    add_quad(s.triangles, b, c[0], c[1], c[2], c[3]);
  }
}

void opaque(Scene& s, SceneRng& rng) {
  const double W = s.header.width, H = s.header.height;
  for (int k = 0; k < 24; ++k) {
    Rgb col{static_cast<float>(rng.uniform(0.1, 1)), static_cast<float>(rng.uniform(0.1, 1)),
            static_cast<float>(rng.uniform(0.1, 1))};
    ScreenTriangle t;
    t.draw_id = static_cast<uint32_t>(k);
    for (auto& v : t.v)
      v = vert(rng.uniform(-0.1, 1.1) * W, rng.uniform(-0.1, 1.1) * H, rng.uniform(0.05, 0.95), col, 1.0f);
    s.triangles.push_back(t);
  }
}

/// Foliage: small alpha-mapped leaf quads in clusters (branches), the case
/// hashed alpha testing is made for (Wyman & McGuire 2017). A leaf is a square
/// quad 9-22 px wide at a random angle carrying a kLeafMap x kLeafMap alpha
/// map, sampled nearest-texel: each texel is its own flat-alpha cell of the
/// quad (the rasterizer has no textures). A texel's alpha is the fraction of
/// it inside the leaf's outline (a pointed ellipse), so most texels are 0 or 1
/// and the outline is soft. Each branch is one draw; leaves in generation order.
void foliage(Scene& s, SceneRng& rng) {
  const double W = s.header.width, H = s.header.height;
  s.header.clear_color = {0.55f, 0.70f, 0.90f};  // sky
  constexpr int kBranches = 14, kLeavesPerBranch = 22, kLeafMap = 8, kTexelSamples = 4;
  // The alpha map, the same for every leaf: local (u, v) in [-1, 1]^2, u along the leaf.
  static const auto map = [] {
    std::array<float, kLeafMap * kLeafMap> a{};
    for (int j = 0; j < kLeafMap; ++j)
      for (int i = 0; i < kLeafMap; ++i) {
        int in = 0;
        for (int sj = 0; sj < kTexelSamples; ++sj)
          for (int si = 0; si < kTexelSamples; ++si) {
            const double u = 2.0 * (i + (si + 0.5) / kTexelSamples) / kLeafMap - 1.0;
            const double v = 2.0 * (j + (sj + 0.5) / kTexelSamples) / kLeafMap - 1.0;
            in += std::fabs(v) < 0.55 * std::sqrt(std::max(0.0, 1.0 - u * u));
          }
        a[size_t(j * kLeafMap + i)] = float(in) / float(kTexelSamples * kTexelSamples);
      }
    return a;
  }();
  for (int b = 0; b < kBranches; ++b) {
    const double bx = W * rng.uniform(0.15, 0.85), by = H * rng.uniform(0.15, 0.85);
    const double bz = rng.uniform(0.15, 0.85), spread = W * rng.uniform(0.06, 0.12);
    const Rgb base{static_cast<float>(rng.uniform(0.10, 0.30)), static_cast<float>(rng.uniform(0.40, 0.70)),
                   static_cast<float>(rng.uniform(0.08, 0.25))};
    for (int l = 0; l < kLeavesPerBranch; ++l) {
      const double cx = bx + spread * rng.normal(), cy = by + spread * rng.normal();
      const double half = rng.uniform(4.5, 11.0) * W / 256.0, ang = rng.uniform(0, 2 * kPi);
      const double z = std::clamp(bz + 0.05 * rng.normal(), 0.02, 0.98);
      const float shade = static_cast<float>(rng.uniform(0.7, 1.15));
      const Rgb c{std::min(1.0f, base[0] * shade), std::min(1.0f, base[1] * shade), std::min(1.0f, base[2] * shade)};
      const double ca = std::cos(ang), sa = std::sin(ang);
      auto at = [&](int i, int j, float alpha) {
        const double u = 2.0 * i / kLeafMap - 1.0, v = 2.0 * j / kLeafMap - 1.0;
        const double lx = u * half, ly = v * half;
        return vert(cx + ca * lx - sa * ly, cy + sa * lx + ca * ly, z + 0.002 * u, c, alpha);
      };
      for (int j = 0; j < kLeafMap; ++j)
        for (int i = 0; i < kLeafMap; ++i) {
          const float a = map[size_t(j * kLeafMap + i)];
          add_quad(s.triangles, uint32_t(b), at(i, j, a), at(i + 1, j, a), at(i + 1, j + 1, a), at(i, j + 1, a));
        }
    }
  }
}

struct Builder {
  SceneInfo info;
  void (*build)(Scene&, SceneRng&);
};

const std::vector<Builder>& builders() {
  static const std::vector<Builder> b = {
      {{"testcard", "LK Fig. 1 left: alpha ramp 0->1, a 0.61 quad, 5 overlapping 0.75 quads; white on black", 256, 192},
       testcard},
      {{"eight-layers", "LK Fig. 3: 8 full-screen white surfaces, alpha 0.1, over black", 128, 128}, eight_layers},
      {{"enderton-1", "red over green, alpha 0.45 each, over blue: exact pixel (0.45, 0.2475, 0.3025)", 64, 64},
       enderton1},
      {{"enderton-2", "4 white surfaces, alpha 0.25, over 25% gray: exact pixel 0.7626953125", 64, 64}, enderton2},
      {{"cloth", "folded tessellated coloured sheet, 3-6 layers, alpha 0.4, triangles shuffled (LK Fig. 10)", 256, 256},
       cloth},
      {{"smoke", "96 overlapping billboards, alpha 0.05, unsorted (LK Fig. 8)", 256, 256}, smoke},
      {{"opaque", "24 interpenetrating opaque triangles", 256, 256}, opaque},
      {{"foliage", "308 alpha-mapped leaves in 14 branches: alpha mostly 0 or 1, soft edges (hashed alpha)", 256, 256},
       foliage},
  };
  return b;
}

}  // namespace

const std::vector<SceneInfo>& scene_catalog() {
  static const std::vector<SceneInfo> c = [] {
    std::vector<SceneInfo> v;
    for (const auto& b : builders()) v.push_back(b.info);
    return v;
  }();
  return c;
}

Scene build_scene(const SceneParams& p) {
  const Builder* b = nullptr;
  for (const auto& x : builders())
    if (x.info.name == p.name) b = &x;
  if (!b) {
    std::string names;
    for (const auto& x : builders()) names += (names.empty() ? "" : ", ") + x.info.name;
    throw SceneError("unknown scene '" + p.name + "' (known: " + names + ")");
  }
  if (!is_valid_spp(p.spp))
    throw SceneError("--spp " + std::to_string(p.spp) + " is not one of 1, 2, 4, 8, 16, 32, 64");
  Scene s;
  TraceHeader& h = s.header;
  h.width = p.width ? p.width : b->info.width;
  h.height = p.height ? p.height : b->info.height;
  h.spp = p.spp;
  h.depth_mode = p.depth_mode;
  h.color_format = p.color_format;
  h.compression = p.compression;
  h.checksummed = p.checksum;
  h.positions = standard_sample_positions(p.spp);
  h.scene_name = p.name;
  std::string err = validate_header(h);
  if (!err.empty()) throw SceneError("scene " + p.name + ": " + err);
  SceneRng rng(p.seed);
  b->build(s, rng);
  number_primitives(s.triangles);
  return s;
}

RasterStats rasterize_scene(const Scene& s, const std::function<void(const Fragment&)>& emit) {
  Rasterizer r(s.header);
  for (const auto& t : s.triangles) r.rasterize(t, emit);
  return r.stats();
}

RasterStats write_scene_trace(const SceneParams& p, const std::string& path) {
  Scene s = build_scene(p);
  TraceWriter w(path, s.header);
  RasterStats st = rasterize_scene(s, [&](const Fragment& f) { w.write(f); });
  w.finish();
  return st;
}

}  // namespace ropsim
