// Numeric formats shared by the golden model and the SystemC units.
// See docs/numerics.md for the rules; every function here is the single
// definition used by both models, so bit-exactness is structural.
#pragma once
#include <cstdint>

#include "rtl_models/algo/bits.h"

namespace ropsim {

inline constexpr int kMaxSpp = 64;

/// Bytes of one sample in the ROP's buffers: depth is binary32, colour RGB
/// binary16 (docs/numerics.md); the host store keeps these. An 8-bit
/// target's sample in memory is RGBA8 (surface_bytes.h).
inline constexpr uint32_t kDepthSampleBytes = 4;
inline constexpr uint32_t kColorSampleBytes = 6;
inline constexpr uint32_t kRgba8SampleBytes = 4;

/// Widths of the datapaths that a what-if study may narrow. Defaults are the
/// 32-bit arithmetic of Laine & Karras 2011, Figure 4.
struct Numerics {
  int hash_bits = 32;        ///< width of the alpha-reference hash datapath (8..32)
  int alpha_bits = 32;       ///< fixed-point precision of the fragment opacity (1..32)
  int surface_id_bits = 32;  ///< width of the per-pixel surface id register (1..32); wraps
};

/// Returns an error message for an out-of-range field, or nullptr when valid.
inline const char* validate(const Numerics& n) {
  if (n.hash_bits < 8 || n.hash_bits > 32) return "hash_bits must be in [8, 32]";
  if (n.alpha_bits < 1 || n.alpha_bits > 32) return "alpha_bits must be in [1, 32]";
  if (n.surface_id_bits < 1 || n.surface_id_bits > 32) return "surface_id_bits must be in [1, 32]";
  return nullptr;
}

/// 1, 2, 4, 8, 16, 32 or 64 samples per pixel.
inline bool is_valid_spp(int spp) { return spp >= 1 && spp <= kMaxSpp && is_pow2(unsigned(spp)); }

}  // namespace ropsim
