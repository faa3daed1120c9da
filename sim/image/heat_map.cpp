#include "sim/image/heat_map.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "sim/image/image_io.h"
#include "util/codec/image_codec.h"

namespace ropsim {

namespace {

// Viridis at 9 evenly spaced stops (matplotlib's table), 8-bit sRGB.
constexpr unsigned char kViridis[9][3] = {{68, 1, 84},    {71, 45, 123}, {59, 82, 139},  {44, 114, 142}, {33, 145, 140},
                                          {39, 173, 129}, {92, 200, 99}, {170, 220, 50}, {253, 231, 37}};

// A 5 x 7 pixel font for the titles and the colour bar: digits, lower-case
// letters (upper case is drawn as lower case) and the punctuation of map
// names, units and numbers; each glyph's rows top to bottom, '#' lit.
struct Glyph {
  char c;
  const char* rows[7];
};
constexpr Glyph kFont[] = {
    {'0', {".###.", "#...#", "#..##", "#.#.#", "##..#", "#...#", ".###."}},
    {'1', {"..#..", ".##..", "..#..", "..#..", "..#..", "..#..", ".###."}},
    {'2', {".###.", "#...#", "....#", "...#.", "..#..", ".#...", "#####"}},
    {'3', {"#####", "...#.", "..#..", "...#.", "....#", "#...#", ".###."}},
    {'4', {"...#.", "..##.", ".#.#.", "#..#.", "#####", "...#.", "...#."}},
    {'5', {"#####", "#....", "####.", "....#", "....#", "#...#", ".###."}},
    {'6', {"..##.", ".#...", "#....", "####.", "#...#", "#...#", ".###."}},
    {'7', {"#####", "....#", "...#.", "..#..", ".#...", ".#...", ".#..."}},
    {'8', {".###.", "#...#", "#...#", ".###.", "#...#", "#...#", ".###."}},
    {'9', {".###.", "#...#", "#...#", ".####", "....#", "...#.", ".##.."}},
    {'a', {".....", ".....", ".###.", "....#", ".####", "#...#", ".####"}},
    {'b', {"#....", "#....", "#.##.", "##..#", "#...#", "#...#", "####."}},
    {'c', {".....", ".....", ".###.", "#....", "#....", "#...#", ".###."}},
    {'d', {"....#", "....#", ".##.#", "#..##", "#...#", "#...#", ".####"}},
    {'e', {".....", ".....", ".###.", "#...#", "#####", "#....", ".###."}},
    {'f', {"..##.", ".#..#", ".#...", "###..", ".#...", ".#...", ".#..."}},
    {'g', {".....", ".####", "#...#", "#...#", ".####", "....#", ".###."}},
    {'h', {"#....", "#....", "#.##.", "##..#", "#...#", "#...#", "#...#"}},
    {'i', {"..#..", ".....", ".##..", "..#..", "..#..", "..#..", ".###."}},
    {'j', {"...#.", ".....", "..##.", "...#.", "...#.", "#..#.", ".##.."}},
    {'k', {"#....", "#....", "#..#.", "#.#..", "##...", "#.#..", "#..#."}},
    {'l', {".##..", "..#..", "..#..", "..#..", "..#..", "..#..", ".###."}},
    {'m', {".....", ".....", "##.#.", "#.#.#", "#.#.#", "#...#", "#...#"}},
    {'n', {".....", ".....", "#.##.", "##..#", "#...#", "#...#", "#...#"}},
    {'o', {".....", ".....", ".###.", "#...#", "#...#", "#...#", ".###."}},
    {'p', {".....", ".....", "####.", "#...#", "####.", "#....", "#...."}},
    {'q', {".....", ".....", ".##.#", "#..##", ".####", "....#", "....#"}},
    {'r', {".....", ".....", "#.##.", "##..#", "#....", "#....", "#...."}},
    {'s', {".....", ".....", ".###.", "#....", ".###.", "....#", "####."}},
    {'t', {".#...", ".#...", "###..", ".#...", ".#...", ".#..#", "..##."}},
    {'u', {".....", ".....", "#...#", "#...#", "#...#", "#..##", ".##.#"}},
    {'v', {".....", ".....", "#...#", "#...#", "#...#", ".#.#.", "..#.."}},
    {'w', {".....", ".....", "#...#", "#...#", "#.#.#", "#.#.#", ".#.#."}},
    {'x', {".....", ".....", "#...#", ".#.#.", "..#..", ".#.#.", "#...#"}},
    {'y', {".....", ".....", "#...#", "#...#", ".####", "....#", ".###."}},
    {'z', {".....", ".....", "#####", "...#.", "..#..", ".#...", "#####"}},
    {'.', {".....", ".....", ".....", ".....", ".....", ".##..", ".##.."}},
    {',', {".....", ".....", ".....", ".....", ".##..", "..#..", ".#..."}},
    {'-', {".....", ".....", ".....", "#####", ".....", ".....", "....."}},
    {'+', {".....", "..#..", "..#..", "#####", "..#..", "..#..", "....."}},
    {'_', {".....", ".....", ".....", ".....", ".....", ".....", "#####"}},
    {'(', {"...#.", "..#..", ".#...", ".#...", ".#...", "..#..", "...#."}},
    {')', {".#...", "..#..", "...#.", "...#.", "...#.", "..#..", ".#..."}},
    {'/', {".....", "....#", "...#.", "..#..", ".#...", "#....", "....."}},
    {'%', {"##...", "##..#", "...#.", "..#..", ".#...", "#..##", "...##"}},
    {':', {".....", ".##..", ".##..", ".....", ".##..", ".##..", "....."}},
    {'=', {".....", ".....", "#####", ".....", "#####", ".....", "....."}},
};
constexpr uint32_t kGlyphW = 5, kGlyphH = 7, kAdvance = 6, kMargin = 4;

const Glyph* glyph(char c) {
  c = char(std::tolower(static_cast<unsigned char>(c)));
  for (const Glyph& g : kFont)
    if (g.c == c) return &g;
  return nullptr;
}

/// An RGB canvas of the PNG's bands, black.
struct Canvas {
  uint32_t width, height;
  std::vector<unsigned char> px;
  Canvas(uint32_t w, uint32_t h) : width(w), height(h), px(size_t(w) * h * 3, 0) {}
  void set(uint32_t x, uint32_t y, const unsigned char rgb[3]) {
    if (x < width && y < height) std::memcpy(&px[(size_t(y) * width + x) * 3], rgb, 3);
  }
  const unsigned char* row(uint32_t y) const { return &px[size_t(y) * width * 3]; }
};

constexpr unsigned char kWhite[3] = {255, 255, 255};

/// Draws s white with its top-left corner at (x0, y0), each font pixel k x k.
void draw_text(Canvas& c, uint32_t x0, uint32_t y0, const std::string& s, uint32_t k) {
  uint32_t x = x0;
  for (char ch : s) {
    if (const Glyph* g = glyph(ch))
      for (uint32_t r = 0; r < kGlyphH * k; ++r)
        for (uint32_t q = 0; q < kGlyphW * k; ++q)
          if (g->rows[r / k][q / k] == '#') c.set(x + q, y0 + r, kWhite);
    x += kAdvance * k;
  }
}

/// The colour bar's three labels: 0, max / 2, max.
std::vector<std::string> bar_labels(double max) {
  max = std::max(max, 0.0);
  return {"0", legend_label(max / 2.0), legend_label(max)};
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

uint32_t heat_text_scale(uint32_t width) { return width >= 400 ? 2 : 1; }

uint32_t heat_text_width(const std::string& s, uint32_t k) {
  return s.empty() ? 0 : uint32_t(s.size()) * kAdvance * k - (kAdvance - kGlyphW) * k;
}

std::string heat_title(const HeatLabels& labels) {
  return labels.unit.empty() ? labels.title : labels.title + " (" + labels.unit + ")";
}

uint32_t heat_png_width(uint32_t width, const HeatLabels& labels, double max) {
  const uint32_t k = heat_text_scale(width);
  uint32_t labels_w = 0;
  for (const std::string& l : bar_labels(max)) labels_w += heat_text_width(l, k) + 2 * kAdvance * k;
  return std::max({width, 2 * kMargin + heat_text_width(heat_title(labels), k), 2 * kMargin + labels_w});
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
                                           const HeatLabels& labels, const std::string& path) {
  const uint32_t k = heat_text_scale(width), cw = heat_png_width(width, labels, max);
  // The title band: the title centred vertically, at the left margin.
  Canvas title(cw, kTitleRows);
  draw_text(title, kMargin, (kTitleRows - kGlyphH * k) / 2, heat_title(labels), k);
  // The colour bar band: the scale from 0 (left) to max (right) over the
  // canvas less its margins, rows 4 to 15; ticks below it at 0, max / 2 and
  // max, each labelled (the first left-aligned on its tick, the middle one
  // centred, the last right-aligned).
  Canvas bar(cw, kBarRows);
  const uint32_t x0 = kMargin, x1 = cw - 1 - kMargin, bar_top = 4, bar_bottom = 16;
  for (uint32_t x = x0; x <= x1; ++x) {
    unsigned char c[3];
    heat_color(double(x - x0) / double(std::max(1u, x1 - x0)), c);
    for (uint32_t y = bar_top; y < bar_bottom; ++y) bar.set(x, y, c);
  }
  const std::vector<std::string> text = bar_labels(max);
  const uint32_t ticks[3] = {x0, x0 + (x1 - x0) / 2, x1};
  for (int i = 0; i < 3; ++i) {
    for (uint32_t y = bar_bottom; y < bar_bottom + 4; ++y) bar.set(ticks[i], y, kWhite);
    const uint32_t w = heat_text_width(text[size_t(i)], k);
    const uint32_t at = i == 0 ? ticks[0] : i == 1 ? ticks[1] - std::min(ticks[1], w / 2) : ticks[2] + 1 - w;
    draw_text(bar, at, bar_bottom + 6, text[size_t(i)], k);
  }
  std::vector<float> v(width);
  try {
    return encode_png_rows(
        int(cw), int(height + kLegendRows),
        [&](int yy, void* row) {
          auto* o = static_cast<unsigned char*>(row);
          const uint32_t y = uint32_t(yy);
          if (y < kTitleRows) {
            std::memcpy(o, title.row(y), size_t(cw) * 3);
          } else if (y >= kTitleRows + height) {
            std::memcpy(o, bar.row(y - kTitleRows - height), size_t(cw) * 3);
          } else {
            rows(y - kTitleRows, v.data());
            for (uint32_t x = 0; x < width; ++x) heat_color(max > 0 ? v[x] / max : 0.0, o + 3 * x);
            std::memset(o + 3 * size_t(width), 0, size_t(cw - width) * 3);
          }
        },
        path);
  } catch (const ImageCodecError& e) {
    throw ImageError(e.what());
  }
}

}  // namespace ropsim
