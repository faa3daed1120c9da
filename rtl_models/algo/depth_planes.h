// The rasterizer-plane depth encoder (the default): a tile's planes are the
// planes of the primitives whose samples it holds, as the ROP receives them
// from the rasterizer, with a per-sample plane selector
// (docs/architecture.md "Surface compression").
#pragma once
#include <cstdint>

#include "rtl_models/algo/bits.h"
#include "rtl_models/algo/compression_format.h"

namespace ropsim {

/// A sample's plane key: the primitive whose depth it holds, as the ROP
/// receives it from the rasterizer (draw and primitive index; a primitive's
/// depths all lie on the plane the rasterizer set up for it), or the clear
/// plane. Keys are compared, never decoded. (Draw 2^32 - 1's primitive
/// 2^32 - 1 shares the clear plane's key.)
inline constexpr uint64_t kClearPlaneKey = ~uint64_t{0};
inline uint64_t plane_key(uint32_t draw_id, uint32_t prim_id) { return uint64_t(draw_id) << 32 | prim_id; }

/// The distinct plane keys of a tile's n samples, up to `most`: returns
/// their count, or most + 1 as soon as there are more.
inline uint32_t distinct_planes(const uint64_t* key, uint32_t n, uint32_t most) {
  uint64_t seen[9];
  uint32_t count = 0, last = 0;
  for (uint32_t i = 0; i < n; ++i) {
    const uint64_t k = key[i];
    if (count && seen[last] == k) continue;  // runs of one primitive are the common case
    uint32_t j = 0;
    while (j < count && seen[j] != k) ++j;
    if (j == count) {
      if (count == most) return most + 1;
      seen[count++] = k;
    }
    last = j;
  }
  return count;
}

/// The rasterizer-plane encoding's size in bits of a tile of n samples
/// covered by p planes (p <= depth_planes): the fit encoder's layout with no
/// residual (docs/architecture.md) -- header, p planes of kDepthPlaneBits
/// (the rasterizer's plane: its depth at the tile's corner and its two
/// gradients, 32 bits each) and a ceil(log2 p)-bit selector per sample.
inline uint64_t plane_encoding_bits(uint32_t p, uint32_t n) {
  return kDepthHeaderBits + uint64_t(kDepthPlaneBits) * p + uint64_t(n) * uint64_t(log2_ceil(p));
}

/// A depth tile's plane keys (pixels * spp, the address map's order).
struct DepthPlanesIn {
  const uint64_t* key;
  uint32_t pixels;
  int spp;
};

}  // namespace ropsim
