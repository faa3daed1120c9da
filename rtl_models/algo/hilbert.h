// Hilbert-curve pixel index (LK 2011 §3.1: pixelId along a Hilbert curve so
// that nearby pixels get nearby indices and no 2x2 / 4x4 block structure).
#pragma once
#include <cstdint>

#include "rtl_models/algo/bits.h"

namespace ropsim {

/// Smallest power of two >= max(width, height): the side of the Hilbert grid.
inline uint32_t hilbert_side(uint32_t width, uint32_t height) { return next_pow2(width > height ? width : height); }

namespace hilbert_detail {
// The classic quadrant-rotation walk (Wikipedia's xy2d) as a four-state
// machine: the rotations so far only swap the axes and complement both
// coordinates' lower bits, so (swap, complement) is all the state there is,
// and each level is a table lookup on (state, x bit, y bit) giving the
// base-4 digit and the next state.
//   index = state << 2 | bx << 1 | by; entry = digit << 2 | next state.
inline constexpr uint8_t kStep[16] = {
    0 << 2 | 1, 1 << 2 | 0, 3 << 2 | 3, 2 << 2 | 0,  // state 0: identity
    0 << 2 | 0, 3 << 2 | 2, 1 << 2 | 1, 2 << 2 | 1,  // state 1: axes swapped
    2 << 2 | 2, 3 << 2 | 1, 1 << 2 | 2, 0 << 2 | 3,  // state 2: complemented
    2 << 2 | 3, 1 << 2 | 3, 3 << 2 | 0, 0 << 2 | 2,  // state 3: swapped and complemented
};

/// Four levels of kStep in one lookup: index = state << 8 | x nibble << 4 |
/// y nibble (the nibbles' high bits the upper level); entry = the four
/// base-4 digits (8 bits, the upper level's highest) << 2 | next state.
struct Step4Table {
  uint16_t entry[1024];
};

constexpr Step4Table make_step4_table() {
  Step4Table t{};
  for (uint32_t s = 0; s < 4; ++s)
    for (uint32_t x = 0; x < 16; ++x)
      for (uint32_t y = 0; y < 16; ++y) {
        uint32_t state = s, digits = 0;
        for (int k = 3; k >= 0; --k) {
          const uint32_t e = kStep[state << 2 | ((x >> k) & 1u) << 1 | ((y >> k) & 1u)];
          digits = digits << 2 | (e >> 2);
          state = e & 3u;
        }
        t.entry[s << 8 | x << 4 | y] = static_cast<uint16_t>(digits << 2 | state);
      }
  return t;
}

inline constexpr Step4Table kStep4 = make_step4_table();
}  // namespace hilbert_detail

/// Canonical rotate-quadrant Hilbert index d of (x, y) on an n x n grid
/// (n a power of two). For n = 4 the rows (y = 0..3) are
/// 0 1 14 15 / 3 2 13 12 / 4 7 8 11 / 5 6 9 10.
inline uint64_t hilbert_xy2d(uint32_t n, uint32_t x, uint32_t y) {
  // The state machine of hilbert_detail::kStep, four levels per lookup. The
  // levels are padded at the top to a multiple of four with zero bits: from
  // state 0 a zero level gives digit 0 and state 1, from state 1 digit 0 and
  // state 0, so starting in state (padding levels) mod 2 the padding adds no
  // digit and leaves state 0 for the grid's top level. No branches on the
  // coordinates, one lookup per four levels.
  const int levels = log2_ceil(n);
  const int groups = (levels + 3) >> 2;
  const uint32_t keep = static_cast<uint32_t>(low_mask(levels));  // bits of x and y above the grid are not read
  x &= keep;
  y &= keep;
  uint32_t state = static_cast<uint32_t>(4 * groups - levels) & 1u;
  uint64_t d = 0;
  for (int g = groups - 1; g >= 0; --g) {
    const uint32_t e = hilbert_detail::kStep4.entry[state << 8 | ((x >> (4 * g)) & 15u) << 4 | ((y >> (4 * g)) & 15u)];
    d = d << 8 | (e >> 2);
    state = e & 3u;
  }
  return d;
}

}  // namespace ropsim
