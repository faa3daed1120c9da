// The heat maps' PNG figures (sim/image/heat_map.h, `ropsim run --maps`,
// docs/reports.md): a title band naming the map and its unit above the map,
// the map's values through the colour scale, and a colour bar below it with
// labelled ticks; a map narrower than its title widens the PNG instead of
// clipping the text.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>

#include "sim/image/heat_map.h"
#include "tests/study_test_util.h"
#include "util/codec/image_codec.h"

namespace fs = std::filesystem;

namespace {

/// An 8-bit pixel of a decoded PNG.
struct Rgb {
  int r, g, b;
};
Rgb at(const ropsim::DecodedImage& im, int x, int y) {
  const float* p = &im.px[(size_t(y) * size_t(im.width) + size_t(x)) * size_t(im.channels)];
  return Rgb{int(std::lround(p[0] * 255)), int(std::lround(p[1] * 255)), int(std::lround(p[2] * 255))};
}
bool white(const Rgb& c) { return c.r == 255 && c.g == 255 && c.b == 255; }

/// The columns [first, last] holding white (text) pixels in rows [y0, y1) of
/// the image; first > last when there are none.
std::pair<int, int> text_columns(const ropsim::DecodedImage& im, int y0, int y1) {
  int first = im.width, last = -1;
  for (int y = y0; y < y1; ++y)
    for (int x = 0; x < im.width; ++x)
      if (white(at(im, x, y))) first = std::min(first, x), last = std::max(last, x);
  return {first, last};
}

}  // namespace

TEST(HeatMap, ThePngNamesTheMapAndItsUnitAboveTheMapAndAColourBarBelow) {
  ropsim_test::Scratch s("ropsim-test-heat-map");
  const ropsim_test::Ran r =
      ropsim_test::ropsim(s.dir,
                          "run --scene eight-layers --spp 4 --width 48 --height 40 --method lk --maps maps "
                          "--quiet --out img.png");
  ASSERT_EQ(r.status, 0) << r.err;
  const ropsim::DecodedImage exr = ropsim::decode_image_file((s.dir / "maps" / "samples_written.exr").string());
  const ropsim::DecodedImage png = ropsim::decode_image_file((s.dir / "maps" / "samples_written.png").string());
  ASSERT_EQ(exr.width, 48);
  ASSERT_EQ(png.height, exr.height + int(ropsim::kLegendRows));
  double max = 0;
  for (size_t i = 0; i < exr.px.size(); i += size_t(exr.channels)) max = std::max(max, double(exr.px[i]));
  ASSERT_GT(max, 0) << "the test needs samples written";
  const ropsim::HeatLabels labels{"samples_written", "samples per pixel"};
  const uint32_t k = ropsim::heat_text_scale(48);
  EXPECT_EQ(uint32_t(png.width), ropsim::heat_png_width(48, labels, max)) << "the PNG is as wide as its title";
  EXPECT_GT(png.width, 48) << "the 48-pixel map is narrower than \"samples_written (samples per pixel)\"";

  // The title band: white text from the left margin, as long as the title
  // (to within a glyph's blank columns), inside the PNG.
  const auto [first, last] = text_columns(png, 0, int(ropsim::kTitleRows));
  ASSERT_LE(first, last) << "no title above the map";
  const int want = int(ropsim::heat_text_width(ropsim::heat_title(labels), k));
  EXPECT_LE(first, 6);
  EXPECT_NEAR(last - first + 1, want, 4.0 * k)
      << "the title's width is not that of \"" << ropsim::heat_title(labels) << "\"";
  EXPECT_LT(last, png.width - 1) << "the title is clipped at the right";

  // The map: each pixel the colour of its value, below the title band.
  int wrong = 0;
  for (int y = 0; y < exr.height; ++y)
    for (int x = 0; x < exr.width; ++x) {
      unsigned char c[3];
      ropsim::heat_color(double(exr.px[(size_t(y) * 48 + size_t(x)) * size_t(exr.channels)]) / max, c);
      const Rgb p = at(png, x, y + int(ropsim::kTitleRows));
      wrong += std::abs(p.r - c[0]) > 1 || std::abs(p.g - c[1]) > 1 || std::abs(p.b - c[2]) > 1;
    }
  EXPECT_EQ(wrong, 0) << "map pixels not the colour of their value under the title band";

  // The colour bar: from the colour of 0 at the left margin to that of the
  // largest value at the right one, brightening (green rises) on the way;
  // labels below it.
  const int bar_y = exr.height + int(ropsim::kTitleRows) + 10;
  unsigned char lo[3], hi[3];
  ropsim::heat_color(0, lo);
  ropsim::heat_color(1, hi);
  const Rgb l = at(png, 4, bar_y), h = at(png, png.width - 5, bar_y);
  EXPECT_EQ(l.g, lo[1]);
  EXPECT_EQ(h.g, hi[1]);
  for (int x = 5; x < png.width - 5; ++x) EXPECT_GE(at(png, x, bar_y).g, at(png, x - 1, bar_y).g) << "column " << x;
  const auto [lf, ll] = text_columns(png, bar_y + 8, png.height);
  EXPECT_LT(lf, 10) << "no label at the bar's left end (0)";
  EXPECT_GT(ll, png.width - 10) << "no label at the bar's right end (the largest value)";
}

TEST(HeatMap, WideMapsKeepTheirWidthAndDrawLargerText) {
  const uint32_t w = 640, h = 8;
  const ropsim::HeatLabels labels{"tile_cycles", "cycles per tile"};
  const auto bytes = ropsim::encode_heat_png(
      w, h,
      [](uint32_t, float* out) {
        for (uint32_t x = 0; x < w; ++x) out[x] = float(x);
      },
      double(w - 1), labels, "t.png");
  const ropsim::DecodedImage png = ropsim::decode_image_memory(bytes.data(), bytes.size(), "png", "t.png");
  EXPECT_EQ(png.width, int(w)) << "a map wider than its text keeps its width (a tile map lies over the frame)";
  EXPECT_EQ(png.height, int(h + ropsim::kLegendRows));
  EXPECT_EQ(ropsim::heat_text_scale(w), 2u);
  // Text at scale 2 is 14 rows tall: count the title band's rows with text.
  int rows = 0;
  for (int y = 0; y < int(ropsim::kTitleRows); ++y) rows += text_columns(png, y, y + 1).first < png.width;
  EXPECT_EQ(rows, 14) << "the title's glyphs are 7 font rows at 2 pixels each";
}
