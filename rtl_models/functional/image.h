// A resolved image: linear RGB, 3 floats per pixel, held in 8 x 8 tiles
// allocated where a pixel is written. Every other pixel is the background
// colour and costs no memory, so an image's memory follows what the scene
// touched, not width x height (a 32768 x 32768 screen with one fragment is
// one tile). Readers go row by row (row()) or pixel by pixel (at()).
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "util/containers/tile_map.h"
#include "util/memory_budget.h"

namespace ropsim {

class Image {
 public:
  static constexpr uint32_t kTileSide = 8;
  struct Tile {
    float rgb[kTileSide * kTileSide * 3];
  };

  Image() : tiles_(0, 0) {}
  Image(uint32_t width, uint32_t height, std::array<float, 3> background = {0, 0, 0})
      : width(width), height(height), background_(background), tiles_(width, height) {}
  /// A dense image (rgb: width * height * 3 floats, row-major), every tile held.
  static Image from_dense(uint32_t width, uint32_t height, const std::vector<float>& rgb);

  Image(Image&&) = default;
  Image& operator=(Image&&) = default;
  Image(const Image& o);
  Image& operator=(const Image& o);

  /// The pixel's colour (the background's if its tile was never written).
  const float* at(uint32_t x, uint32_t y) const {
    const Tile* t = tiles_.find(x, y);
    return t ? t->rgb + offset(x, y) : background_.data();
  }
  /// The pixel's colour to write; its tile is allocated (as the background) on first write.
  float* at(uint32_t x, uint32_t y) { return tile(x, y).rgb + offset(x, y); }

  /// Row y, width * 3 floats, into out.
  void row(uint32_t y, float* out) const;
  /// True if no pixel of row y was written (it is all background).
  bool row_untouched(uint32_t y) const { return tile_rows_.empty() || tile_rows_[y >> 3] == 0; }
  /// Every pixel, row-major (for small images and tests).
  std::vector<float> dense() const;

  const std::array<float, 3>& background() const { return background_; }
  /// Replaces every value v, the background's and every held pixel's, by f(v).
  template <class F>
  void transform(F&& f) {
    for (float& v : background_) v = f(v);
    tiles_.for_each([&f](uint32_t, uint32_t, const Tile& t) {
      for (float& v : const_cast<Tile&>(t).rgb) v = f(v);  // this image's own tile
    });
  }
  size_t tiles() const { return tiles_.tiles(); }
  /// Memory held by the pixels: the tiles and their directory.
  size_t bytes() const { return tiles_.tiles() * sizeof(Tile) + tiles_.directory_bytes(); }

  uint32_t width = 0, height = 0;  ///< set by the constructor; do not change

 private:
  static size_t offset(uint32_t x, uint32_t y) { return size_t((y & 7u) << 3 | (x & 7u)) * 3; }
  Tile& tile(uint32_t x, uint32_t y);

  std::array<float, 3> background_{0, 0, 0};
  TileMap<Tile> tiles_;
  std::vector<uint32_t> tile_rows_;  ///< touched tiles per row of tiles (empty until the first)
  BudgetShare mem_;                  // the tiles' bytes in the run's memory budget (--memory-limit)
};

bool operator==(const Image& a, const Image& b);
inline bool operator!=(const Image& a, const Image& b) { return !(a == b); }

}  // namespace ropsim
