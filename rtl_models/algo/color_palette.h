// MSAA colour compression: per pixel its k <= K distinct binary16 RGB
// colours and, when k > 1, a ceil(log2 K)-bit index per sample
// (docs/architecture.md "Surface compression").
#pragma once
#include <cstdint>
#include <cstring>
#include <vector>

#include "rtl_models/algo/bit_stream.h"
#include "rtl_models/algo/bits.h"
#include "rtl_models/algo/numerics.h"

namespace ropsim {

/// A colour tile to compress: pixels * spp samples of `bps` bytes each (the
/// colour buffer's RGB binary16, 6 bytes; the same format serves the blend
/// render targets, 2 to 16 bytes a sample).
struct ColorTileIn {
  const uint8_t* bytes;  ///< [(pixel * spp + sample) * bps + byte]
  uint32_t pixels;
  int spp;
  uint32_t bps = kColorSampleBytes;
};

namespace compression_detail {
/// A sample's bytes (bps <= 8) as one integer: equal keys, equal bytes.
inline uint64_t sample_key(const uint8_t* q, uint32_t bps) {
  uint32_t lo = 0;
  uint16_t mid = 0;
  uint64_t v = 0;
  switch (bps) {
    case 6:  // the colour buffer's RGB binary16
      std::memcpy(&lo, q, 4);
      std::memcpy(&mid, q + 4, 2);
      return uint64_t(lo) | uint64_t(mid) << 32;
    case 8:
      std::memcpy(&v, q, 8);
      return v;
    case 4:
      std::memcpy(&lo, q, 4);
      return lo;
    default:
      std::memcpy(&v, q, bps);
      return v;
  }
}
/// Collects one pixel's distinct sample values (first appearance order) and
/// each sample's index; false when there are more than K.
inline bool pixel_palette(const ColorTileIn& t, uint32_t p, uint32_t K, uint32_t& k, uint32_t* first, uint8_t* idx) {
  const uint32_t spp = uint32_t(t.spp), bps = t.bps;
  const uint8_t* c = t.bytes + size_t(p) * spp * bps;
  k = 0;
  for (uint32_t s = 0; s < spp; ++s) {
    uint32_t j = 0;
    while (j < k && std::memcmp(c + size_t(first[j]) * bps, c + size_t(s) * bps, bps) != 0) ++j;
    if (j == k) {
      if (k == K || k == 8) return false;
      first[k++] = s;
    }
    if (idx) idx[s] = uint8_t(j);
  }
  return true;
}
/// The number k of a pixel's distinct sample values, key(s) the value of
/// sample s as one integer; false when there are more than kmax.
template <class Key>
inline bool count_distinct(uint32_t spp, uint32_t kmax, uint32_t& k, Key key) {
  uint64_t keys[8];
  k = 0;
  for (uint32_t s = 0; s < spp; ++s) {
    const uint64_t v = key(s);
    uint32_t j = 0;
    while (j < k && keys[j] != v) ++j;
    if (j == k) {
      if (k == kmax) return false;
      keys[k++] = v;
    }
  }
  return true;
}
}  // namespace compression_detail

/// The encoded size of a colour tile with at most K distinct values per
/// pixel, in bits, or ~0 when some pixel has more than K. Per pixel:
/// ceil(log2 K) bits k - 1, k values of 8 bps bits, and when k > 1 an index
/// of ceil(log2 K) bits per sample (values in order of first appearance).
inline uint64_t color_tile_bits(const ColorTileIn& t, uint32_t K, uint32_t* max_k = nullptr) {
  using compression_detail::sample_key;
  const int ib = log2_ceil(K);
  uint64_t bits = 0;
  uint32_t mk = 0, first[8];
  const uint32_t spp = uint32_t(t.spp), bps = t.bps;
  const uint32_t kmax = std::min(K, 8u);
  for (uint32_t p = 0; p < t.pixels; ++p) {
    const uint8_t* c = t.bytes + size_t(p) * spp * bps;
    uint32_t k = 1;
    bool fits = true;
    if (std::memcmp(c, c + bps, size_t(spp - 1) * bps) == 0) {
      // Every sample of the pixel holds the first one's bytes (the common case).
    } else if (bps == kColorSampleBytes) {
      fits = compression_detail::count_distinct(
          spp, kmax, k, [c](uint32_t s) { return sample_key(c + size_t(s) * kColorSampleBytes, kColorSampleBytes); });
    } else if (bps <= 8) {
      // The same count as pixel_palette, with each sample's bytes as one
      // integer key (the colour buffer's 6 bytes, most blend targets').
      fits = compression_detail::count_distinct(spp, kmax, k,
                                                [c, bps](uint32_t s) { return sample_key(c + size_t(s) * bps, bps); });
    } else {
      fits = compression_detail::pixel_palette(t, p, K, k, first, nullptr);
    }
    if (!fits) {
      if (max_k) *max_k = K + 1;
      return ~uint64_t{0};
    }
    mk = std::max(mk, k);
    bits += uint64_t(ib) + uint64_t(8 * t.bps) * k + (k > 1 ? uint64_t(t.spp) * uint64_t(ib) : 0);
  }
  if (max_k) *max_k = mk;
  return bits;
}

/// The encoded tile; the caller checked that it fits (color_tile_bits).
inline std::vector<uint8_t> encode_color_tile(const ColorTileIn& t, uint32_t K) {
  const int ib = log2_ceil(K);
  BitWriter w;
  const uint32_t spp = uint32_t(t.spp);
  std::vector<uint8_t> idx(spp);
  uint32_t first[8];
  for (uint32_t p = 0; p < t.pixels; ++p) {
    uint32_t k = 0;
    compression_detail::pixel_palette(t, p, K, k, first, idx.data());
    w.put(k - 1, ib);
    const uint8_t* c = t.bytes + size_t(p) * spp * t.bps;
    for (uint32_t j = 0; j < k; ++j)
      for (uint32_t b = 0; b < t.bps; ++b) w.put(c[size_t(first[j]) * t.bps + b], 8);
    if (k > 1)
      for (uint32_t s = 0; s < spp; ++s) w.put(idx[s], ib);
  }
  return w.bytes();
}

inline void decode_color_tile(const std::vector<uint8_t>& in, uint32_t pixels, int spp, uint32_t K, uint32_t bps,
                              uint8_t* out) {
  const int ib = log2_ceil(K);
  BitReader rd(in);
  std::vector<uint8_t> pal(size_t(8) * bps);
  for (uint32_t p = 0; p < pixels; ++p) {
    const uint32_t k = uint32_t(rd.get(ib)) + 1;
    for (uint32_t j = 0; j < k && j < 8; ++j)
      for (uint32_t b = 0; b < bps; ++b) pal[size_t(j) * bps + b] = uint8_t(rd.get(8));
    for (int s = 0; s < spp; ++s) {
      uint64_t j = k > 1 ? rd.get(ib) : 0;
      if (j >= 8) j = 0;
      std::memcpy(out + (size_t(p) * size_t(spp) + size_t(s)) * bps, &pal[j * bps], bps);
    }
  }
}

}  // namespace ropsim
