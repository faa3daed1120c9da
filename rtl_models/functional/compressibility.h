// The compressibility of a ROP's final buffers (the functional fidelity's
// view of surface compression, compression.h): every memory tile of the
// depth, colour and render-target surfaces compressed once at the end of the
// frame, as memory holds them (surface_bytes.h), and counted by block-size
// class. Needs no cycle model, so studies
// can use it cheaply; the cycle model's traffic uses the same tile sizes.
#pragma once
#include <array>
#include <cstdint>
#include <memory>

#include "rtl_models/algo/buffers.h"
#include "rtl_models/algo/compression.h"
#include "rtl_models/functional/sample_store.h"
#include "rtl_models/functional/surface_bytes.h"

namespace ropsim {

/// One surface's compressibility.
struct BufferCompression {
  uint64_t tiles = 0;                         ///< memory tiles of the surface (the whole screen)
  uint64_t tiles_cleared = 0;                 ///< tiles holding only the clear value (fast clear: no bytes)
  uint64_t bytes_uncompressed = 0;            ///< the other tiles' bytes, uncompressed
  uint64_t bytes_compressed = 0;              ///< the same tiles in their block sizes
  std::array<uint64_t, 4> tiles_per_class{};  ///< [j]: tiles stored in U >> j bytes (0: uncompressed)
  uint64_t metadata_bytes = 0;                ///< the surface's state bits, every tile
  BufferCompression& operator+=(const BufferCompression& o) {
    tiles += o.tiles;
    tiles_cleared += o.tiles_cleared;
    bytes_uncompressed += o.bytes_uncompressed;
    bytes_compressed += o.bytes_compressed;
    for (size_t j = 0; j < tiles_per_class.size(); ++j) tiles_per_class[j] += o.tiles_per_class[j];
    metadata_bytes += o.metadata_bytes;
    return *this;
  }
};

struct CompressionStats {
  bool measured = false;
  std::array<bool, kBuffers> compressed{};  ///< the surfaces measured
  std::array<BufferCompression, kBuffers> buffers{};
};

/// Whether the surface b takes part in compression under `setup` for a
/// store with these buffers (depth: compression.depth; colour and the blend
/// targets: compression.color; tracker and slab's layers never).
bool compressible(Buffer b, const CompressionSetup& setup, const SampleStore& store);

/// Compresses every memory tile of the store's compressible surfaces.
CompressionStats measure_compressibility(const SampleStore& store, const CompressionSetup& setup);

/// A tile's state in memory: cleared (fast clear), or its compressed size.
struct TileState {
  bool cleared = false;
  TileSize size;
  float max_depth = 1.0f;  ///< depth: the farthest stored depth of the tile (Hi-Z)
};

/// Compresses single memory tiles of a store's current state (the cycle
/// model's writeback of a tile): the memory tile of surface b holding pixel
/// (x, y), i.e. the tile_pixels pixels of its address-map run.
class TileCompressor {
 public:
  TileCompressor(const SampleStore& store, const CompressionFormat& f);
  ~TileCompressor();
  /// size = false: only `cleared` and `max_depth`, without compressing.
  /// The n patches are written over the tile's bytes first, in order.
  TileState state(Buffer b, uint32_t x, uint32_t y, bool size = true, const TilePatch* patches = nullptr,
                  size_t n = 0) const;
  const CompressionFormat& format() const { return f_; }

 private:
  struct Clear;
  const SampleStore& store_;
  CompressionFormat f_;
  SurfaceBytes bytes_;  ///< the store's surfaces in memory
  std::unique_ptr<Clear> clear_;
};

}  // namespace ropsim
