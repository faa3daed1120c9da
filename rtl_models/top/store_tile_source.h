// The compressor's view of the functional store (compression_model.h's
// TileSource): a memory tile's contents compressed as the store holds them
// when asked (compressibility.h's TileCompressor). The cycle model and the
// analytical model compress their writebacks' tiles through it, and the
// sampled model too, with the tiles a live-point does not hold.
#pragma once
#include <array>
#include <cstdint>

#include "rtl_models/algo/bits.h"
#include "rtl_models/algo/compression.h"
#include "rtl_models/functional/compressibility.h"
#include "rtl_models/memory/compression_model.h"

namespace ropsim {

class StoreTileSource : public TileSource {
 public:
  StoreTileSource(const SampleStore& store, const CompressionFormat& f)
      : store_(store), comp_(store, f), tiles_x_(ceil_div(store.header().width, 8u)), tile_pixels_(f.tile_pixels) {}
  TileInfo tile(Buffer b, uint64_t tile, bool size, const TilePatch* undo, size_t n) override {
    const uint64_t pix = tile * tile_pixels_, t = pix / 64, p = pix % 64;
    const uint32_t x = uint32_t((t % tiles_x_) * 8 + (p & 7u)), y = uint32_t((t / tiles_x_) * 8 + (p >> 3));
    if (absent_set_[size_t(b)] && !store_.tile_map().find(x, y)) return absent(b, tile);
    const TileState st = comp_.state(b, x, y, size, undo, n);
    return TileInfo{st.cleared, st.size.size_class, st.max_depth};
  }
  /// A tile of surface b in an 8 x 8 tile the store never allocated is not
  /// cleared, of class j for a share classes[j] / sum of such tiles (which
  /// ones: a hash of the tile's index), its farthest depth max_depth
  /// (sampled simulation: a tile whose lines only the warming brought into a
  /// cache, its contents not in the live-point).
  void set_absent(Buffer b, const std::array<uint64_t, 4>& classes, float max_depth) {
    absent_[size_t(b)] = classes;
    absent_depth_ = max_depth;
    absent_set_[size_t(b)] = true;
  }

 private:
  TileInfo absent(Buffer b, uint64_t tile) const {
    const std::array<uint64_t, 4>& c = absent_[size_t(b)];
    const uint64_t sum = c[0] + c[1] + c[2] + c[3];
    TileInfo t;
    t.max_depth = absent_depth_;
    if (sum == 0) return t;
    uint64_t h = (tile + 1) * 0x9E3779B97F4A7C15ull;  // the tile's pick, fixed
    h = (h ^ (h >> 29)) % sum;
    while (h >= c[size_t(t.size_class)]) h -= c[size_t(t.size_class++)];
    return t;
  }
  const SampleStore& store_;
  TileCompressor comp_;
  uint64_t tiles_x_, tile_pixels_;
  std::array<std::array<uint64_t, 4>, kBuffers> absent_{};
  std::array<bool, kBuffers> absent_set_{};
  float absent_depth_ = 1.0f;
};

}  // namespace ropsim
