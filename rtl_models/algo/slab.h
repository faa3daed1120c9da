// Stochastic Layered Alpha Blending (Wyman 2016, "Exploring and expanding the
// continuum of OIT algorithms"): per pixel, k layers, each a depth, a colour
// (RGB binary16) and a b-bit coverage mask. A fragment gets a stratified
// random b-bit mask of floor(alpha |C| + xi) bits among its candidate bits C
// (the bits of its covered samples); it is inserted in depth order only where
// it is not occluded (some of its bits not covered by nearer layers); with
// more than k layers the furthest is discarded. The resolve walks the layers
// front to back: each bit takes the colour of the nearest layer that covers
// it, uncovered bits the clear colour. With k at least the number of
// fragments this is stochastic transparency with b samples. No SystemC, no
// state beyond the pixel's: shared by the golden model and the SystemC units.
#pragma once
#include <array>
#include <cstdint>
#include <cstring>

#include "rtl_models/algo/method_kernels.h"

namespace ropsim {

inline constexpr int kMaxSlabLayers = 16;
inline constexpr int kMaxSlabBits = 64;

/// Returns an error message for an out-of-range k or b, or nullptr when valid.
inline const char* validate_slab(int layers, int bits) {
  if (layers < 1 || layers > kMaxSlabLayers) return "slab layers (k) must be in [1, 16]";
  if (bits < 1 || bits > kMaxSlabBits) return "slab bits (b) must be in [1, 64]";
  return nullptr;
}

/// Bytes of one pixel's SLAB state in the ROP's memory: per layer binary32
/// depth, RGB binary16 colour and the ceil(b / 8)-byte mask, plus one byte of
/// layer count.
constexpr uint32_t slab_pixel_bytes(int layers, int bits) {
  return uint32_t(layers) * (4u + 6u + uint32_t(bits + 7) / 8u) + 1u;
}

/// One pixel's layers, nearest first (layers [0, count) are valid).
struct SlabPixel {
  uint8_t count = 0;
  float depth[kMaxSlabLayers] = {};
  uint64_t mask[kMaxSlabLayers] = {};
  uint16_t rgb[kMaxSlabLayers][3] = {};
  bool operator==(const SlabPixel& o) const {
    if (count != o.count) return false;
    for (int i = 0; i < count; ++i)
      if (std::memcmp(&depth[i], &o.depth[i], 4) != 0 || mask[i] != o.mask[i] ||
          std::memcmp(rgb[i], o.rgb[i], sizeof rgb[i]) != 0)
        return false;
    return true;
  }
};

/// The mask bits each sample of the pixel owns: bit j belongs to sample
/// floor(j spp / b) (b >= spp: b / spp bits per sample; b < spp: bit j stands
/// for that one sample).
inline std::array<uint64_t, 64> slab_sample_bits(int spp, int bits) {
  std::array<uint64_t, 64> t{};
  for (int j = 0; j < bits; ++j) t[size_t(j * spp / bits)] |= uint64_t{1} << j;
  return t;
}

/// The fragment's stratified mask: R = floor(alpha |C| + xi) of the candidate
/// bits C, chosen uniformly at random by the partial Fisher-Yates shuffle of
/// enderton_pick (the same hashes). Adds the hashes it computed to *hashes.
inline uint64_t slab_mask(uint64_t a_fixed, int alpha_bits, uint64_t candidates, uint64_t key, uint32_t* hashes) {
  int list[64];
  uint32_t m = 0;
  for (uint64_t c = candidates; c; c &= c - 1) list[m++] = __builtin_ctzll(c);
  const uint32_t r = enderton_count(a_fixed, alpha_bits, m, key);
  enderton_pick(list, m, r, key);
  uint64_t mask = 0;
  for (uint32_t j = 0; j < r; ++j) mask |= uint64_t{1} << list[j];
  *hashes += r + 1;
  return mask;
}

/// Every bit of mask is covered by layers nearer than z (a layer at the same
/// depth does not occlude: the later fragment wins ties, as in the depth test).
inline bool slab_occluded(const SlabPixel& p, float z, uint64_t mask) {
  uint64_t nearer = 0;
  for (int i = 0; i < p.count && p.depth[i] < z; ++i) nearer |= p.mask[i];
  return (mask & ~nearer) == 0;
}

/// Inserts the layer (z, mask, rgb) before the first layer at depth >= z; with
/// more than k layers the furthest (the last) is discarded. Returns the index
/// it was inserted at, or k if it was itself the furthest and discarded.
inline int slab_insert(SlabPixel& p, int k, float z, uint64_t mask, const uint16_t rgb[3]) {
  int at = 0;
  while (at < p.count && p.depth[at] < z) ++at;
  if (at >= k) return k;                           // beyond the k nearest: it is the one dropped
  const int last = p.count < k ? p.count : k - 1;  // the furthest falls off when full
  for (int i = last; i > at; --i) {
    p.depth[i] = p.depth[i - 1];
    p.mask[i] = p.mask[i - 1];
    std::memcpy(p.rgb[i], p.rgb[i - 1], sizeof p.rgb[i]);
  }
  p.depth[at] = z;
  p.mask[at] = mask;
  std::memcpy(p.rgb[at], rgb, sizeof p.rgb[at]);
  if (p.count < k) ++p.count;
  return at;
}

/// Front-to-back resolve: sum over layers of colour x (bits it covers that no
/// nearer layer covers), plus the clear colour x (bits no layer covers), over
/// b. rgb are the layers' colours as floats; binary64 sums in layer order.
inline void slab_resolve(const SlabPixel& p, int bits, const float (*rgb)[3], const float clear[3], float out[3]) {
  double sum[3] = {0, 0, 0};
  uint64_t covered = 0;
  for (int i = 0; i < p.count; ++i) {
    const int n = __builtin_popcountll(p.mask[i] & ~covered);
    covered |= p.mask[i];
    for (int c = 0; c < 3; ++c) sum[c] += double(rgb[i][c]) * n;
  }
  const int open = bits - __builtin_popcountll(covered);
  for (int c = 0; c < 3; ++c) out[c] = float((sum[c] + double(clear[c]) * open) / bits);
}

/// slab_resolve over a background that varies by sample (a pre-pass's
/// opaque and blended draws): each bit no layer covers takes the colour of
/// the sample that owns it (bits_of: slab_sample_bits), background holding
/// spp RGB triples.
inline void slab_resolve_over(const SlabPixel& p, int bits, const float (*rgb)[3], const uint64_t* bits_of, int spp,
                              const float* background, float out[3]) {
  double sum[3] = {0, 0, 0};
  uint64_t covered = 0;
  for (int i = 0; i < p.count; ++i) {
    const int n = __builtin_popcountll(p.mask[i] & ~covered);
    covered |= p.mask[i];
    for (int c = 0; c < 3; ++c) sum[c] += double(rgb[i][c]) * n;
  }
  for (int s = 0; s < spp; ++s) {
    const int n = __builtin_popcountll(bits_of[s] & ~covered);
    for (int c = 0; c < 3; ++c) sum[c] += double(background[3 * s + c]) * n;
  }
  for (int c = 0; c < 3; ++c) out[c] = float(sum[c] / bits);
}

}  // namespace ropsim
