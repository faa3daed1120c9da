// Hilbert-curve pixel index (LK 2011 §3.1: pixelId along a Hilbert curve so
// that nearby pixels get nearby indices and no 2x2 / 4x4 block structure).
#pragma once
#include <cstdint>

#include "bits.h"

namespace ropsim {

/// Smallest power of two >= max(width, height): the side of the Hilbert grid.
inline uint32_t hilbert_side(uint32_t width, uint32_t height) { return next_pow2(width > height ? width : height); }

/// Canonical rotate-quadrant Hilbert index d of (x, y) on an n x n grid
/// (n a power of two). For n = 4 the rows (y = 0..3) are
/// 0 1 14 15 / 3 2 13 12 / 4 7 8 11 / 5 6 9 10.
inline uint64_t hilbert_xy2d(uint32_t n, uint32_t x, uint32_t y) {
  // The classic quadrant-rotation walk (Wikipedia's xy2d) as a four-state
  // machine: the rotations so far only swap the axes and complement both
  // coordinates' lower bits, so (swap, complement) is all the state there is,
  // and each level is a table lookup on (state, x bit, y bit) giving the
  // base-4 digit and the next state. No branches, one step per level.
  //   index = state << 2 | bx << 1 | by; entry = digit << 2 | next state.
  static constexpr uint8_t kStep[16] = {
      0 << 2 | 1, 1 << 2 | 0, 3 << 2 | 3, 2 << 2 | 0,  // state 0: identity
      0 << 2 | 0, 3 << 2 | 2, 1 << 2 | 1, 2 << 2 | 1,  // state 1: axes swapped
      2 << 2 | 2, 3 << 2 | 1, 1 << 2 | 2, 0 << 2 | 3,  // state 2: complemented
      2 << 2 | 3, 1 << 2 | 3, 3 << 2 | 0, 0 << 2 | 2,  // state 3: swapped and complemented
  };
  uint64_t d = 0;
  uint32_t state = 0;
  for (int k = log2_ceil(n) - 1; k >= 0; --k) {
    const uint32_t e = kStep[state << 2 | ((x >> k) & 1u) << 1 | ((y >> k) & 1u)];
    d = d << 2 | (e >> 2);
    state = e & 3u;
  }
  return d;
}

}  // namespace ropsim
