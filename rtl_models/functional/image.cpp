#include "rtl_models/functional/image.h"

#include <algorithm>
#include <cstring>

namespace ropsim {

Image::Tile& Image::tile(uint32_t x, uint32_t y) {
  return tiles_.get(x, y, [this, y](uint32_t, uint32_t) {
    mem_.add(sizeof(Tile), "the resolved image's touched tiles");
    if (tile_rows_.empty()) tile_rows_.assign((height + kTileSide - 1) / kTileSide, 0);
    ++tile_rows_[y >> 3];
    auto t = std::make_unique<Tile>();
    for (size_t i = 0; i < kTileSide * kTileSide; ++i)
      std::memcpy(t->rgb + 3 * i, background_.data(), 3 * sizeof(float));
    return t;
  });
}

Image::Image(const Image& o) : width(o.width), height(o.height), background_(o.background_), tiles_(o.width, o.height) {
  o.tiles_.for_each([&](uint32_t x0, uint32_t y0, const Tile& t) { tile(x0, y0) = t; });
}

Image& Image::operator=(const Image& o) {
  if (this != &o) *this = Image(o);
  return *this;
}

Image Image::from_dense(uint32_t width, uint32_t height, const std::vector<float>& rgb) {
  Image img(width, height);
  for (uint32_t y = 0; y < height; ++y)
    for (uint32_t x = 0; x < width; ++x)
      std::memcpy(img.at(x, y), &rgb[(size_t(y) * width + x) * 3], 3 * sizeof(float));
  return img;
}

void Image::row(uint32_t y, float* out) const {
  for (uint32_t x0 = 0; x0 < width; x0 += kTileSide) {
    const uint32_t n = std::min(kTileSide, width - x0);
    const Tile* t = tiles_.find(x0, y);
    if (t) {
      std::memcpy(out + size_t(x0) * 3, t->rgb + offset(x0, y), size_t(n) * 3 * sizeof(float));
    } else {
      for (uint32_t k = 0; k < n; ++k) std::memcpy(out + size_t(x0 + k) * 3, background_.data(), 3 * sizeof(float));
    }
  }
}

std::vector<float> Image::dense() const {
  std::vector<float> v(size_t(width) * height * 3);
  for (uint32_t y = 0; y < height; ++y) row(y, v.data() + size_t(y) * width * 3);
  return v;
}

bool operator==(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height) return false;
  std::vector<float> ra(size_t(a.width) * 3), rb(ra.size());
  for (uint32_t y = 0; y < a.height; ++y) {
    a.row(y, ra.data());
    b.row(y, rb.data());
    if (std::memcmp(ra.data(), rb.data(), ra.size() * sizeof(float)) != 0) return false;
  }
  return true;
}

}  // namespace ropsim
