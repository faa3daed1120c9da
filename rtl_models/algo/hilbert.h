// Hilbert-curve pixel index (LK 2011 §3.1: pixelId along a Hilbert curve so
// that nearby pixels get nearby indices and no 2x2 / 4x4 block structure).
#pragma once
#include <cstdint>

namespace ropsim {

/// Smallest power of two >= max(width, height): the side of the Hilbert grid.
inline uint32_t hilbert_side(uint32_t width, uint32_t height) {
  uint32_t m = width > height ? width : height;
  uint32_t n = 1;
  while (n < m) n <<= 1;
  return n;
}

/// Canonical rotate-quadrant Hilbert index d of (x, y) on an n x n grid
/// (n a power of two). For n = 4 the rows (y = 0..3) are
/// 0 1 14 15 / 3 2 13 12 / 4 7 8 11 / 5 6 9 10.
inline uint64_t hilbert_xy2d(uint32_t n, uint32_t x, uint32_t y) {
  uint64_t d = 0;
  for (uint32_t s = n >> 1; s > 0; s >>= 1) {
    const uint32_t rx = (x & s) ? 1u : 0u;
    const uint32_t ry = (y & s) ? 1u : 0u;
    d += uint64_t{s} * s * ((3u * rx) ^ ry);
    if (ry == 0) {  // rotate the quadrant
      if (rx == 1) {
        x = s - 1 - (x & (s - 1));
        y = s - 1 - (y & (s - 1));
      }
      const uint32_t t = x;
      x = y;
      y = t;
    }
  }
  return d;
}

}  // namespace ropsim
