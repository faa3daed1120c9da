// The compressor's view of the functional store (compression_model.h's
// TileSource): a memory tile's contents compressed as the store holds them
// when asked (compressibility.h's TileCompressor). The cycle model and the
// analytical model both compress their writebacks' tiles through it.
#pragma once
#include <cstdint>

#include "bits.h"
#include "compressibility.h"
#include "compression_model.h"

namespace ropsim {

class StoreTileSource : public TileSource {
 public:
  StoreTileSource(const SampleStore& store, const CompressionFormat& f)
      : comp_(store, f), tiles_x_(ceil_div(store.header().width, 8u)), tile_pixels_(f.tile_pixels) {}
  TileInfo tile(Buffer b, uint64_t tile, bool size, const TilePatch* undo, size_t n) override {
    const uint64_t pix = tile * tile_pixels_, t = pix / 64, p = pix % 64;
    const uint32_t x = uint32_t((t % tiles_x_) * 8 + (p & 7u)), y = uint32_t((t / tiles_x_) * 8 + (p >> 3));
    const TileState st = comp_.state(b, x, y, size, undo, n);
    return TileInfo{st.cleared, st.size.size_class, st.max_depth};
  }

 private:
  TileCompressor comp_;
  uint64_t tiles_x_, tile_pixels_;
};

}  // namespace ropsim
