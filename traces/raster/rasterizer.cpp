#include "traces/raster/rasterizer.h"

#include <algorithm>
#include <cmath>

namespace ropsim {

Rasterizer::Rasterizer(const TraceHeader& header) : h_(header) {}

void Rasterizer::rasterize(const ScreenTriangle& t, const std::function<void(const Fragment&)>& emit) {
  ++stats_.triangles;
  constexpr double kScale = 1 << kSubpixelBits;
  int64_t X[3], Y[3];
  for (int i = 0; i < 3; ++i) {
    X[i] = std::llround(t.v[i].x * kScale);
    Y[i] = std::llround(t.v[i].y * kScale);
  }
  // Twice the signed area; orient counter-clockwise on screen (y down) so that
  // inside means every edge function >= 0.
  int64_t area = (X[1] - X[0]) * (Y[2] - Y[0]) - (Y[1] - Y[0]) * (X[2] - X[0]);
  if (area == 0) {
    ++stats_.culled_degenerate;
    return;
  }
  int idx[3] = {0, 1, 2};
  if (area < 0) {
    std::swap(idx[1], idx[2]);
    area = -area;
  }
  int64_t x[3], y[3];
  for (int i = 0; i < 3; ++i) {
    x[i] = X[idx[i]];
    y[i] = Y[idx[i]];
  }
  // Edge e goes from vertex e to vertex e+1; its function is >= 0 inside.
  int64_t ex[3], ey[3], bias[3];
  for (int e = 0; e < 3; ++e) {
    int n = (e + 1) % 3;
    ex[e] = x[n] - x[e];
    ey[e] = y[n] - y[e];
    // Top-left rule: with this orientation a left edge has dy < 0 and a top
    // edge has dy == 0, dx > 0. Samples exactly on other edges are outside.
    bool top_left = ey[e] < 0 || (ey[e] == 0 && ex[e] > 0);
    bias[e] = top_left ? 0 : -1;
  }
  auto edge = [&](int e, int64_t px, int64_t py) { return ex[e] * (py - y[e]) - ey[e] * (px - x[e]) + bias[e]; };

  // Depth plane and attribute interpolation through barycentrics (in pixels).
  const double inv_area = 1.0 / static_cast<double>(area);
  const ScreenVertex* v[3] = {&t.v[idx[0]], &t.v[idx[1]], &t.v[idx[2]]};
  auto bary = [&](double px, double py, double b[3]) {  // px, py in sub-pixel units
    for (int e = 0; e < 3; ++e) {
      int n = (e + 1) % 3;
      // weight of the vertex opposite edge e is edge e's function / area
      double w = static_cast<double>(ex[e]) * (py - static_cast<double>(y[e])) -
                 static_cast<double>(ey[e]) * (px - static_cast<double>(x[e]));
      b[(n + 1) % 3] = w * inv_area;
    }
  };
  // dz per pixel from the plane through the snapped vertices.
  double b00[3], b10[3], b01[3];
  bary(0, 0, b00);
  bary(kScale, 0, b10);
  bary(0, kScale, b01);
  auto zat = [&](const double b[3]) { return b[0] * v[0]->z + b[1] * v[1]->z + b[2] * v[2]->z; };
  double dzdx = zat(b10) - zat(b00), dzdy = zat(b01) - zat(b00);
  // Optionally the plane through the unsnapped vertices: z = pz + pa*(x - px) + pb*(y - py), in pixels.
  bool unsnapped = t.depth_from_unsnapped;
  double pa = 0, pb = 0;
  if (unsnapped) {
    const ScreenVertex &a = t.v[0], &b = t.v[1], &c = t.v[2];
    const double d = (b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y);
    pa = ((b.z - a.z) * (c.y - a.y) - (c.z - a.z) * (b.y - a.y)) / d;
    pb = ((b.x - a.x) * (c.z - a.z) - (c.x - a.x) * (b.z - a.z)) / d;
    unsnapped = d != 0 && std::isfinite(pa) && std::isfinite(pb);
    if (unsnapped) {
      dzdx = pa;
      dzdy = pb;
    }
  }
  auto zplane = [&](double sx, double sy) {  // unsnapped plane at a point in pixels
    return t.v[0].z + pa * (sx - t.v[0].x) + pb * (sy - t.v[0].y);
  };

  int64_t minx = std::min({x[0], x[1], x[2]}), maxx = std::max({x[0], x[1], x[2]});
  int64_t miny = std::min({y[0], y[1], y[2]}), maxy = std::max({y[0], y[1], y[2]});
  int64_t px0 = std::max<int64_t>(0, minx >> kSubpixelBits);
  int64_t py0 = std::max<int64_t>(0, miny >> kSubpixelBits);
  int64_t px1 = std::min<int64_t>(int64_t(h_.width) - 1, maxx >> kSubpixelBits);
  int64_t py1 = std::min<int64_t>(int64_t(h_.height) - 1, maxy >> kSubpixelBits);

  Fragment f;
  f.draw_id = t.draw_id;
  f.prim_id = t.prim_id;
  const int spp = h_.spp;
  for (int64_t py = py0; py <= py1; ++py) {
    for (int64_t px = px0; px <= px1; ++px) {
      const int64_t bx = px << kSubpixelBits, by = py << kSubpixelBits;
      uint64_t cov = 0;
      int64_t sx_sum = 0, sy_sum = 0;
      for (int s = 0; s < spp; ++s) {
        const int64_t sx = bx + h_.positions[s].x, sy = by + h_.positions[s].y;
        if (edge(0, sx, sy) >= 0 && edge(1, sx, sy) >= 0 && edge(2, sx, sy) >= 0) {
          cov |= uint64_t{1} << s;
          sx_sum += sx;
          sy_sum += sy;
        }
      }
      if (!cov) continue;
      const int n = __builtin_popcountll(cov);
      double bc[3], bz[3];
      bary(double(sx_sum) / n, double(sy_sum) / n, bc);
      if (t.perspective) {
        double q[3], sum = 0;
        for (int k = 0; k < 3; ++k) sum += (q[k] = bc[k] * v[k]->inv_w);
        for (int k = 0; k < 3; ++k) bc[k] = q[k] / sum;
      }
      bary(double(bx) + kScale / 2, double(by) + kScale / 2, bz);
      f.x = static_cast<uint16_t>(px);
      f.y = static_cast<uint16_t>(py);
      f.coverage = cov;
      f.z0 = static_cast<float>(unsnapped ? zplane(double(px) + 0.5, double(py) + 0.5) : zat(bz));
      f.dzdx = static_cast<float>(dzdx);
      f.dzdy = static_cast<float>(dzdy);
      for (int s = 0; s < spp && h_.depth_mode == DepthMode::kPerSample; ++s) {
        if (!(cov >> s & 1)) continue;
        double b[3];
        bary(double(bx + h_.positions[s].x), double(by + h_.positions[s].y), b);
        const double zs = unsnapped
                              ? zplane(double(px) + h_.positions[s].x / kScale, double(py) + h_.positions[s].y / kScale)
                              : zat(b);
        f.z[s] = static_cast<float>(std::clamp(zs, 0.0, 1.0));
      }
      for (int c = 0; c < 3; ++c)
        f.rgb[c] =
            std::max(0.0f, static_cast<float>(bc[0] * v[0]->rgb[c] + bc[1] * v[1]->rgb[c] + bc[2] * v[2]->rgb[c]));
      f.alpha =
          static_cast<float>(std::clamp(bc[0] * v[0]->alpha + bc[1] * v[1]->alpha + bc[2] * v[2]->alpha, 0.0, 1.0));
      ++stats_.fragments;
      stats_.covered_samples += n;
      emit(f);
    }
  }
}

}  // namespace ropsim
