#include "heat_map.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "image_codec.h"
#include "image_io.h"

namespace ropsim {

namespace {

// Viridis at 9 evenly spaced stops (matplotlib's table), 8-bit sRGB.
constexpr unsigned char kViridis[9][3] = {{68, 1, 84},    {71, 45, 123}, {59, 82, 139},  {44, 114, 142}, {33, 145, 140},
                                          {39, 173, 129}, {92, 200, 99}, {170, 220, 50}, {253, 231, 37}};

// A 3 x 5 pixel font for the legend's labels: rows top to bottom, bit 2 the
// left column.
struct Glyph {
  char c;
  unsigned char rows[5];
};
constexpr Glyph kFont[] = {
    {'0', {7, 5, 5, 5, 7}}, {'1', {2, 6, 2, 2, 7}}, {'2', {7, 1, 7, 4, 7}}, {'3', {7, 1, 7, 1, 7}},
    {'4', {5, 5, 7, 1, 1}}, {'5', {7, 4, 7, 1, 7}}, {'6', {7, 4, 7, 5, 7}}, {'7', {7, 1, 1, 1, 1}},
    {'8', {7, 5, 7, 5, 7}}, {'9', {7, 5, 7, 1, 7}}, {'.', {0, 0, 0, 0, 2}}, {'e', {0, 7, 7, 4, 7}},
    {'+', {0, 2, 7, 2, 0}}, {'-', {0, 0, 7, 0, 0}},
};

const Glyph* glyph(char c) {
  for (const Glyph& g : kFont)
    if (g.c == c) return &g;
  return nullptr;
}

/// Draws text (scale 2: 6 x 10 pixels per glyph, 2 pixels apart) at column x0
/// of the legend rows, white.
void draw_text(std::vector<unsigned char>& legend, uint32_t width, uint32_t x0, uint32_t y0, const std::string& s) {
  uint32_t x = x0;
  for (char c : s) {
    if (const Glyph* g = glyph(c))
      for (uint32_t r = 0; r < 10; ++r)
        for (uint32_t k = 0; k < 6; ++k)
          if ((g->rows[r / 2] >> (2 - k / 2)) & 1u) {
            const uint32_t px = x + k, py = y0 + r;
            if (px < width && py < kLegendRows) std::memset(&legend[(size_t(py) * width + px) * 3], 255, 3);
          }
    x += 8;
  }
}

}  // namespace

void heat_color(double t, unsigned char rgb[3]) {
  if (!(t > 0)) t = 0;
  if (t > 1) t = 1;
  const double f = t * 8.0;
  const int i = std::min(7, int(f));
  const double u = f - i;
  for (int c = 0; c < 3; ++c)
    rgb[c] = (unsigned char)std::lround(kViridis[i][c] + u * (kViridis[i + 1][c] - kViridis[i][c]));
}

std::string legend_label(double v) {
  char b[32];
  if (v == std::floor(v) && std::fabs(v) < 1e9)
    std::snprintf(b, sizeof b, "%.0f", v);
  else
    std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

std::vector<unsigned char> encode_heat_exr(uint32_t width, uint32_t height, const MapRows& rows,
                                           const std::string& path) {
  std::vector<float> v(width);
  try {
    return encode_exr_rows(
        int(width), int(height),
        [&](int y, void* row) {
          rows(uint32_t(y), v.data());
          float* o = static_cast<float*>(row);
          for (uint32_t x = 0; x < width; ++x) o[3 * x] = o[3 * x + 1] = o[3 * x + 2] = v[x];
        },
        path);
  } catch (const ImageCodecError& e) {
    throw ImageError(e.what());
  }
}

std::vector<unsigned char> encode_heat_png(uint32_t width, uint32_t height, const MapRows& rows, double max,
                                           const std::string& path) {
  // The legend: a dark strip, the scale as a bar over its middle rows, the
  // labels 0 (left) and max (right) above it.
  std::vector<unsigned char> legend(size_t(width) * kLegendRows * 3, 0);
  for (uint32_t x = 0; x < width; ++x) {
    unsigned char c[3];
    heat_color(width > 1 ? double(x) / double(width - 1) : 1.0, c);
    for (uint32_t y = 12; y < kLegendRows; ++y) std::memcpy(&legend[(size_t(y) * width + x) * 3], c, 3);
  }
  const std::string hi = legend_label(std::max(max, 0.0));
  draw_text(legend, width, 1, 1, "0");
  const uint32_t hi_w = uint32_t(hi.size()) * 8;
  if (width > hi_w + 12) draw_text(legend, width, width - hi_w, 1, hi);
  std::vector<float> v(width);
  try {
    return encode_png_rows(
        int(width), int(height + kLegendRows),
        [&](int y, void* row) {
          auto* o = static_cast<unsigned char*>(row);
          if (uint32_t(y) >= height) {
            std::memcpy(o, &legend[size_t(uint32_t(y) - height) * width * 3], size_t(width) * 3);
            return;
          }
          rows(uint32_t(y), v.data());
          for (uint32_t x = 0; x < width; ++x) heat_color(max > 0 ? v[x] / max : 0.0, o + 3 * x);
        },
        path);
  } catch (const ImageCodecError& e) {
    throw ImageError(e.what());
  }
}

}  // namespace ropsim
