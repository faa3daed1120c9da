// A resolved image: linear RGB, row-major, 3 floats per pixel.
#pragma once
#include <cstdint>
#include <vector>

namespace ropsim {

struct Image {
  uint32_t width = 0, height = 0;
  std::vector<float> rgb;
  float* at(uint32_t x, uint32_t y) { return &rgb[(size_t(y) * width + x) * 3]; }
  const float* at(uint32_t x, uint32_t y) const { return &rgb[(size_t(y) * width + x) * 3]; }
};

}  // namespace ropsim
