// Lossless compression of the ROP's depth and MSAA colour surfaces, per
// memory tile (docs/architecture.md "Surface compression" gives the bit
// layouts this file implements):
//   - depth, rasterizer-plane encoder (the default): the planes of the
//     primitives whose depths the tile holds, as the rasterizer set them up
//     (the clear value is one more, constant plane), and a per-sample plane
//     selector; the tile compresses when at most P planes cover it, else it
//     is stored uncompressed;
//   - depth, fit encoder (a design option): up to P plane equations fitted to
//     the stored depths in the integer domain of the binary32 bit pattern
//     (monotone for depths in [0, 1]), a per-sample plane selector and a
//     per-sample signed residual of r bits (r = 0 when the planes are exact),
//     or the tile uncompressed;
//   - colour: per pixel its k <= K distinct binary16 RGB colours and, when
//     k > 1, a ceil(log2 K)-bit index per sample, or the tile uncompressed;
//   - a tile's compressed size is rounded up to one of the block sizes
//     U, U/2, ..., U/2^(classes-1) (U the uncompressed bytes); a tile that
//     needs more than U/2 is stored uncompressed;
//   - per tile, metadata state bits: 0 = cleared (fast clear), 1 + j = stored
//     in U >> j bytes.
// Pure C++, no SystemC: the functional statistics and the cycle model's
// DRAM traffic call the same functions, and a tile's size is a function of
// its contents alone.
// The format, the bit streams and each encoder have their own header
// (compression_format.h, bit_stream.h, depth_planes.h, depth_fit.h,
// color_palette.h); this one gives a tile's compressed size.
#pragma once
#include <cstdint>

#include "rtl_models/algo/color_palette.h"
#include "rtl_models/algo/compression_format.h"
#include "rtl_models/algo/depth_fit.h"
#include "rtl_models/algo/depth_planes.h"

namespace ropsim {

/// Bytes written over a memory tile's uncompressed bytes before it is
/// compressed: `len` bytes at `offset` (the cycle model's pending writes,
/// compression_model.h).
struct TilePatch {
  uint32_t offset, len;
  const uint8_t* old;
  /// Depth with plane keys: the replaced samples' keys (len / 4 of them,
  /// kDepthSampleBytes each in `old`), as bytes; else nullptr.
  const uint8_t* old_planes = nullptr;
};

/// A tile's compressed form: its block-size class (0 = uncompressed) and the
/// bytes it occupies in memory (U >> class).
struct TileSize {
  int size_class = 0;
  uint64_t bytes = 0;
};

inline TileSize depth_tile_size(const DepthTileIn& t, const CompressionFormat& f) {
  const uint64_t U = uint64_t(t.pixels) * uint64_t(t.spp) * kDepthSampleBytes;
  // Once a fit fits the smallest block, a narrower one cannot do better.
  const uint64_t smallest_bits = (U >> (f.size_classes - 1)) * 8;
  thread_local DepthSamples samples;  // its storage reused tile after tile
  samples.assign(t);
  const DepthFit fit = best_depth_fit(samples, int(f.depth_planes), smallest_bits);
  const int c = fit.ok ? size_class(ceil_div(fit.bits, uint64_t{8}), U, f) : 0;
  return {c, U >> c};
}

/// The rasterizer-plane encoder's size: compressed when at most
/// depth_planes planes cover the tile (its depths are then exactly the
/// planes' values at the samples: the ROP wrote each from its primitive's
/// plane), else uncompressed.
inline TileSize plane_depth_tile_size(const DepthPlanesIn& t, const CompressionFormat& f) {
  const uint32_t n = t.pixels * uint32_t(t.spp);
  const uint64_t U = uint64_t(n) * kDepthSampleBytes;
  const uint32_t p = distinct_planes(t.key, n, f.depth_planes);
  const int c = p <= f.depth_planes ? size_class(ceil_div(plane_encoding_bits(p, n), uint64_t{8}), U, f) : 0;
  return {c, U >> c};
}

inline TileSize color_tile_size(const ColorTileIn& t, const CompressionFormat& f) {
  const uint64_t U = uint64_t(t.pixels) * uint64_t(t.spp) * t.bps;
  const uint64_t b = color_tile_bits(t, f.color_k);
  const int c = b == ~uint64_t{0} ? 0 : size_class(ceil_div(b, uint64_t{8}), U, f);
  return {c, U >> c};
}

}  // namespace ropsim
