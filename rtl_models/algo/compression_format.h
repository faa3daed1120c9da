// The surface compression format's parameters (the design's [compression]
// section): the depth encoder, the tile, the block-size classes and the
// metadata state bits of each tile (compression.h has the encoders).
#pragma once
#include <cstdint>

#include "rtl_models/algo/bits.h"

namespace ropsim {

/// How a depth tile's planes are found (the design's compression.depth_encoder).
enum class DepthEncoder : uint8_t {
  kPlane,  ///< the rasterizer's planes of the primitives the tile holds (a GPU's plane encoder)
  kFit,    ///< planes fitted to the stored depths (fit_depth_tile)
};
inline const char* to_string(DepthEncoder e) { return e == DepthEncoder::kFit ? "fit" : "plane"; }

/// The format parameters (the design's [compression] section, hw_config.h).
struct CompressionFormat {
  uint32_t tile_pixels = 16;  ///< pixels of a memory tile: 8, 16, 32 or 64 (whole rows of an 8 x 8 tile)
  uint32_t size_classes = 3;  ///< block sizes U, U/2, ..., U/2^(classes-1); 1..4
  uint32_t depth_planes = 4;  ///< P, plane equations per depth tile; 1..8
  uint32_t color_k = 4;       ///< K, distinct colours per pixel; 1..8
  DepthEncoder depth_encoder = DepthEncoder::kPlane;
};

/// Which surfaces are compressed (the design's compression.depth and
/// compression.color; colour compression also covers the blend targets).
struct CompressionSetup {
  bool depth = false;
  bool color = false;
  CompressionFormat format;
  bool any() const { return depth || color; }
  /// The store keeps each sample's plane key (sample_store.h): the
  /// rasterizer-plane encoder compresses depth.
  bool plane_keys() const { return depth && format.depth_encoder == DepthEncoder::kPlane; }
};

/// Metadata state bits per tile: codes 0 (cleared) and 1 .. classes.
inline int metadata_bits(const CompressionFormat& f) { return log2_ceil(f.size_classes + 1u); }

/// The block-size class of a tile of U uncompressed bytes whose encoding
/// takes `bytes`: j with U >> j the smallest block size >= bytes among
/// j = 1 .. classes - 1, or 0 (uncompressed) when bytes > U / 2 or no
/// encoding exists (bytes = ~0).
inline int size_class(uint64_t bytes, uint64_t U, const CompressionFormat& f) {
  int best = 0;
  for (int j = 1; j < int(f.size_classes); ++j)
    if (bytes <= (U >> j)) best = j;
  return best;
}

/// An encoded depth tile's plane (A, Gx, Gy: 32 bits each) and header
/// (p - 1: 3 bits, r: 5 bits), for both depth encoders.
inline constexpr int kDepthPlaneBits = 96;
inline constexpr int kDepthHeaderBits = 8;  ///< 3 bits p - 1, 5 bits r

}  // namespace ropsim
