// Heat maps: one scalar per pixel (a RunBreakdown map, or the error against
// the reference) as a linear single-value EXR (the value in R, G and B, so
// it sums to its counter) and as a PNG figure: a title band above the map
// naming it and its unit, the map through a perceptual colour scale
// (viridis, dark = 0 to yellow = the largest value), and a colour bar below
// it with ticks labelled 0, half the largest value and the largest value.
// The text is drawn with a built-in 5 x 7 pixel font.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace ropsim {

/// Row y of a map: width values.
using MapRows = std::function<void(uint32_t y, float* out)>;

/// What a heat map's PNG says about it: its title (the map's name) and the
/// unit of its values ("samples per pixel", "cycles per tile").
struct HeatLabels {
  std::string title, unit;
};

/// The map as an EXR (binary32, the value in every channel).
std::vector<unsigned char> encode_heat_exr(uint32_t width, uint32_t height, const MapRows& rows,
                                           const std::string& path);
/// The map as a PNG: kTitleRows of title above, the map's values 0 .. max
/// through the colour scale (max <= 0: all dark), kBarRows of colour bar
/// below. The PNG is heat_png_width(width, labels, max) wide: the map's
/// width, or wider when the text needs it (the map at the left).
std::vector<unsigned char> encode_heat_png(uint32_t width, uint32_t height, const MapRows& rows, double max,
                                           const HeatLabels& labels, const std::string& path);
constexpr uint32_t kTitleRows = 24;
constexpr uint32_t kBarRows = 40;
/// The rows a heat map's PNG adds to the map: its title and its colour bar.
constexpr uint32_t kLegendRows = kTitleRows + kBarRows;
/// The PNG's width for a map width pixels wide.
uint32_t heat_png_width(uint32_t width, const HeatLabels& labels, double max);
/// The title line of the PNG: "title (unit)".
std::string heat_title(const HeatLabels& labels);

/// The colour scale at t in [0, 1] (clamped): 8-bit sRGB.
void heat_color(double t, unsigned char rgb[3]);
/// A label of the colour bar: an integer when v is one, else 3 significant digits.
std::string legend_label(double v);
/// The size of the text's pixels: 2 (10 x 14 pixel glyphs) on a map at least
/// 400 pixels wide, else 1 (5 x 7).
uint32_t heat_text_scale(uint32_t width);
/// The width in pixels of s drawn at scale k (6 k per character, less the
/// last gap). Characters without a glyph are drawn as blanks.
uint32_t heat_text_width(const std::string& s, uint32_t k);

}  // namespace ropsim
