// Heat maps: one scalar per pixel (a RunBreakdown map, or the error against
// the reference) as a linear single-value EXR (the value in R, G and B, so
// it sums to its counter) and as a PNG through a perceptual colour scale
// (viridis, dark = 0 to yellow = the largest value) with a legend strip
// below the image: the scale from 0 to its largest value, labelled.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace ropsim {

/// Row y of a map: width values.
using MapRows = std::function<void(uint32_t y, float* out)>;

/// The map as an EXR (binary32, the value in every channel).
std::vector<unsigned char> encode_heat_exr(uint32_t width, uint32_t height, const MapRows& rows,
                                           const std::string& path);
/// The map as a PNG: values 0 .. max through the colour scale (max <= 0: all
/// dark), and kLegendRows rows of legend below it.
std::vector<unsigned char> encode_heat_png(uint32_t width, uint32_t height, const MapRows& rows, double max,
                                           const std::string& path);
constexpr uint32_t kLegendRows = 16;

/// The colour scale at t in [0, 1] (clamped): 8-bit sRGB.
void heat_color(double t, unsigned char rgb[3]);
/// A label of the legend: an integer when v is one, else 3 significant digits.
std::string legend_label(double v);

}  // namespace ropsim
