// Lossless compression of the ROP's depth and MSAA colour surfaces, per
// memory tile (docs/architecture.md "Surface compression" gives the bit
// layouts this file implements):
//   - depth: up to P plane equations in the integer domain of the binary32
//     bit pattern (monotone for depths in [0, 1]), a per-sample plane
//     selector and a per-sample signed residual of r bits (r = 0 when the
//     planes are exact), or the tile uncompressed;
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
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include "bits.h"
#include "numerics.h"

namespace ropsim {

/// The format parameters (the design's [compression] section, hw_config.h).
struct CompressionFormat {
  uint32_t tile_pixels = 16;  ///< pixels of a memory tile: 8, 16, 32 or 64 (whole rows of an 8 x 8 tile)
  uint32_t size_classes = 3;  ///< block sizes U, U/2, ..., U/2^(classes-1); 1..4
  uint32_t depth_planes = 4;  ///< P, plane equations per depth tile; 1..8
  uint32_t color_k = 4;       ///< K, distinct colours per pixel; 1..8
};

/// Which surfaces are compressed (the design's compression.depth and
/// compression.color; colour compression also covers the blend targets).
struct CompressionSetup {
  bool depth = false;
  bool color = false;
  CompressionFormat format;
  bool any() const { return depth || color; }
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

/// LSB-first bit stream (the encoded tiles).
class BitWriter {
 public:
  void put(uint64_t v, int n) {
    for (int i = 0; i < n; ++i, ++bit_) {
      if ((bit_ & 7) == 0) bytes_.push_back(0);
      bytes_.back() |= uint8_t((v >> i & 1u) << (bit_ & 7));
    }
  }
  uint64_t bits() const { return bit_; }
  const std::vector<uint8_t>& bytes() const { return bytes_; }

 private:
  std::vector<uint8_t> bytes_;
  uint64_t bit_ = 0;
};

class BitReader {
 public:
  explicit BitReader(const std::vector<uint8_t>& b) : b_(b) {}
  uint64_t get(int n) {
    uint64_t v = 0;
    for (int i = 0; i < n; ++i, ++bit_)
      if (bit_ >> 3 < b_.size()) v |= uint64_t(b_[bit_ >> 3] >> (bit_ & 7) & 1u) << i;
    return v;
  }

 private:
  const std::vector<uint8_t>& b_;
  uint64_t bit_ = 0;
};

// ---------------------------------------------------------------- depth

/// One depth plane: u(X, Y) = A + ((Gx X + Gy Y + 2^15) >> 16) in the integer
/// domain of the depth's bit pattern, X = 256 column + pos_x, Y = 256 row +
/// pos_y (1/256 pixel from the tile's top-left corner), Gx, Gy with 16
/// fractional bits per 1/256 pixel. Arithmetic shift; 64-bit products.
struct DepthPlane {
  int32_t a = 0, gx = 0, gy = 0;
  int64_t predict(int64_t X, int64_t Y) const {
    return int64_t(a) + ((int64_t(gx) * X + int64_t(gy) * Y + (int64_t{1} << 15)) >> 16);
  }
};
inline constexpr int kDepthPlaneBits = 96;
inline constexpr int kDepthHeaderBits = 8;  ///< 3 bits p - 1, 5 bits r
/// The residual widths the encoder tries, in order (best_depth_fit).
inline constexpr int kDepthResidualWidths[] = {12, 4, 0};

/// A depth tile to compress: n = pixels * spp samples, pixel-major then
/// sample-major (the address map's order), pixels in rows of 8.
struct DepthTileIn {
  const float* z;   ///< [pixel * spp + sample]
  uint32_t pixels;  ///< tile_pixels
  int spp;
  const uint8_t* pos_x;  ///< [spp], 1/256 pixel from the pixel's top-left corner
  const uint8_t* pos_y;
};

/// A fitted depth tile: its planes, each sample's plane, the residual width.
struct DepthFit {
  bool ok = false;
  int r = 0;
  std::vector<DepthPlane> planes;
  std::vector<uint8_t> sel;  ///< [sample]
  uint64_t bits = 0;         ///< encoded size
};

namespace compression_detail {

inline int64_t sample_u(const DepthTileIn& t, uint32_t i) {
  uint32_t u;
  std::memcpy(&u, &t.z[i], 4);
  return int64_t(u);
}
inline int64_t sample_X(const DepthTileIn& t, uint32_t i) {
  const uint32_t p = i / uint32_t(t.spp), s = i % uint32_t(t.spp);
  return int64_t(256 * (p & 7u) + t.pos_x[s]);
}
inline int64_t sample_Y(const DepthTileIn& t, uint32_t i) {
  const uint32_t p = i / uint32_t(t.spp), s = i % uint32_t(t.spp);
  return int64_t(256 * (p >> 3) + t.pos_y[s]);
}
inline bool fits_i32(int64_t v) { return v >= INT32_MIN && v <= INT32_MAX; }
inline bool in_range(int64_t res, int r) {
  if (r == 0) return res == 0;
  const int64_t h = int64_t{1} << (r - 1);
  return res >= -h && res < h;
}
/// The plane through sample a with gradients gx, gy (A chosen so that a is exact).
inline bool plane_through(const DepthTileIn& t, uint32_t a, int64_t gx, int64_t gy, DepthPlane& pl) {
  if (!fits_i32(gx) || !fits_i32(gy)) return false;
  pl.gx = int32_t(gx);
  pl.gy = int32_t(gy);
  pl.a = 0;
  const int64_t A = sample_u(t, a) - pl.predict(sample_X(t, a), sample_Y(t, a));
  if (!fits_i32(A)) return false;
  pl.a = int32_t(A);
  return true;
}

}  // namespace compression_detail

/// Fits the tile with at most `planes` planes and residual width r: greedy,
/// in sample order. Each plane starts at the first unassigned sample (its
/// anchor), takes its gradients from the same sample of another pixel of
/// its row and of its column (best_gradient below), claims every unassigned sample
/// its prediction meets within r bits, then is refitted once by least
/// squares over the samples it claimed (kept if it claims at least as many).
/// It gives up (no fit) as soon as the planes left could not cover the
/// unassigned samples even claiming twice the most any plane has claimed.
/// Deterministic; any fit it returns decodes exactly (the residuals make up
/// the rest).
inline DepthFit fit_depth_tile(const DepthTileIn& t, int planes, int r) {
  using namespace compression_detail;
  const uint32_t n = t.pixels * uint32_t(t.spp);
  DepthFit f;
  f.r = r;
  f.sel.assign(n, 0xFF);
  uint32_t first = 0;
  auto claim = [&](const DepthPlane& pl, uint8_t k, bool commit, std::vector<uint32_t>* who) {
    uint32_t c = 0;
    for (uint32_t i = first; i < n; ++i)
      if (f.sel[i] == 0xFF || f.sel[i] == k) {
        const bool hit = in_range(sample_u(t, i) - pl.predict(sample_X(t, i), sample_Y(t, i)), r);
        if (commit) f.sel[i] = hit ? k : (f.sel[i] == k ? 0xFF : f.sel[i]);
        if (hit) {
          ++c;
          if (who) who->push_back(i);
        }
      }
    return c;
  };
  const uint32_t spp = uint32_t(t.spp);
  uint32_t most = 0, left = n;
  for (int k = 0; k < planes; ++k) {
    while (first < n && f.sel[first] != 0xFF) ++first;
    if (first == n) break;
    const uint32_t a = first, p = a / spp, s = a % spp;
    // A gradient along x (y): from the same sample of another pixel in the
    // anchor's row (column), the one whose line through the anchor meets
    // the most unassigned same-index samples of that row (column) within r
    // bits; ties to the nearest, then right (below). None: 0.
    const int col = int(p & 7u), row = int(p >> 3), rows = int(t.pixels / 8);
    auto best_gradient = [&](bool along_x) -> int64_t {
      int64_t best_g = 0;
      int best_score = -1;
      const int lim = along_x ? 8 : rows, at = along_x ? col : row;
      for (int d = 1; d < lim; ++d)
        for (int sign : {1, -1}) {
          const int o = at + sign * d;
          if (o < 0 || o >= lim) continue;
          const uint32_t b = uint32_t(along_x ? row * 8 + o : o * 8 + col) * spp + s;
          if (f.sel[b] != 0xFF) continue;
          const int64_t du = sample_u(t, b) - sample_u(t, a);
          // slope per 1/256 pixel with 16 fractional bits: du * 65536 / (256 * sign * d)
          const int64_t g = du * 256 / (sign * d);
          int score = 0;
          for (int q = 0; q < lim; ++q) {
            const uint32_t c = uint32_t(along_x ? row * 8 + q : q * 8 + col) * spp + s;
            if (f.sel[c] != 0xFF) continue;
            const int64_t pred = sample_u(t, a) + ((g * int64_t(256 * (q - at)) + (int64_t{1} << 15)) >> 16);
            if (in_range(sample_u(t, c) - pred, r + 1)) ++score;
          }
          if (score > best_score) {
            best_score = score;
            best_g = g;
          }
        }
      return best_g;
    };
    const int64_t gx = best_gradient(true);
    // y: also from the other samples of the anchor's pixel (a tile of one
    // row, or samples at other sub-pixel heights),
    // given gx; each candidate scored over the anchor's row and column.
    auto score_plane = [&](int64_t cgx, int64_t cgy) {
      DepthPlane q;
      if (!plane_through(t, a, cgx, cgy, q)) return -1;
      int sc = 0;
      for (uint32_t pp = 0; pp < t.pixels; ++pp) {
        if (int(pp >> 3) != row && int(pp & 7u) != col) continue;
        for (uint32_t ss = 0; ss < spp; ++ss) {
          const uint32_t c = pp * spp + ss;
          if (f.sel[c] == 0xFF && in_range(sample_u(t, c) - q.predict(sample_X(t, c), sample_Y(t, c)), r + 1)) ++sc;
        }
      }
      return sc;
    };
    int64_t gy = best_gradient(false);
    int best_sc = score_plane(gx, gy);
    {
      for (uint32_t ss = 0; ss < spp; ++ss) {
        const uint32_t b = p * spp + ss;
        const int64_t dy = sample_Y(t, b) - sample_Y(t, a);
        if (f.sel[b] != 0xFF || dy == 0) continue;
        const int64_t rest = (sample_u(t, b) - sample_u(t, a)) * 65536 - gx * (sample_X(t, b) - sample_X(t, a));
        const int64_t cgy = rest / dy;
        const int sc = score_plane(gx, cgy);
        if (sc > best_sc) {
          best_sc = sc;
          gy = cgy;
        }
      }
    }
    DepthPlane pl;
    if (!plane_through(t, a, gx, gy, pl) && !plane_through(t, a, 0, 0, pl)) break;
    std::vector<uint32_t> who;
    const uint32_t got = claim(pl, uint8_t(k), false, &who);
    // Least-squares refit over the claimed samples (centred on the anchor).
    if (who.size() >= 3) {
      double sxx = 0, sxy = 0, syy = 0, sxu = 0, syu = 0;
      const double X0 = double(sample_X(t, a)), Y0 = double(sample_Y(t, a)), U0 = double(sample_u(t, a));
      for (uint32_t i : who) {
        const double dx = double(sample_X(t, i)) - X0, dy = double(sample_Y(t, i)) - Y0,
                     du = double(sample_u(t, i)) - U0;
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
        sxu += dx * du;
        syu += dy * du;
      }
      const double det = sxx * syy - sxy * sxy;
      if (det > 0) {
        const double ggx = (sxu * syy - syu * sxy) / det, ggy = (syu * sxx - sxu * sxy) / det;
        DepthPlane p2;
        if (std::fabs(ggx) < 2e4 && std::fabs(ggy) < 2e4 &&
            plane_through(t, a, std::llround(ggx * 65536.0), std::llround(ggy * 65536.0), p2) &&
            claim(p2, uint8_t(k), false, nullptr) >= got)
          pl = p2;
      }
    }
    const uint32_t claimed = claim(pl, uint8_t(k), true, nullptr);
    f.planes.push_back(pl);
    // Give up early when the planes left could not cover the rest even
    // claiming twice the most any plane claimed so far.
    most = std::max(most, claimed);
    left -= claimed;
    if (uint64_t(left) > uint64_t(planes - k - 1) * 2 * most) return f;  // not ok
  }
  for (uint32_t i = 0; i < n; ++i)
    if (f.sel[i] == 0xFF) return f;  // not ok
  f.ok = true;
  const uint64_t sel_bits = uint64_t(log2_ceil(uint32_t(f.planes.size())));
  f.bits = kDepthHeaderBits + kDepthPlaneBits * f.planes.size() + uint64_t(n) * (sel_bits + uint64_t(r));
  return f;
}

/// The encoder's fit: residual width 12 first (the most permissive; no fit
/// there and the tile is stored uncompressed), then 4, then 0, each tried
/// only while the wider one fitted; the fewest bits win (ties to the smaller r).
inline DepthFit best_depth_fit(const DepthTileIn& t, int planes) {
  DepthFit best;
  for (int r : kDepthResidualWidths) {
    DepthFit f = fit_depth_tile(t, planes, r);
    if (!f.ok) break;
    if (!best.ok || f.bits <= best.bits) best = std::move(f);
  }
  return best;
}

/// The encoded tile (docs/architecture.md): header (p - 1: 3 bits, r: 5
/// bits), p planes (A, Gx, Gy as 32-bit two's complement), then per sample
/// its selector (ceil(log2 p) bits) and residual (r bits, two's complement).
inline std::vector<uint8_t> encode_depth_fit(const DepthTileIn& t, const DepthFit& f) {
  using namespace compression_detail;
  BitWriter w;
  w.put(f.planes.size() - 1, 3);
  w.put(uint64_t(f.r), 5);
  for (const DepthPlane& p : f.planes) {
    w.put(uint32_t(p.a), 32);
    w.put(uint32_t(p.gx), 32);
    w.put(uint32_t(p.gy), 32);
  }
  const int sb = log2_ceil(uint32_t(f.planes.size()));
  const uint32_t n = t.pixels * uint32_t(t.spp);
  for (uint32_t i = 0; i < n; ++i) {
    w.put(f.sel[i], sb);
    const int64_t res = sample_u(t, i) - f.planes[f.sel[i]].predict(sample_X(t, i), sample_Y(t, i));
    w.put(uint64_t(res), f.r);
  }
  return w.bytes();
}

/// Decodes an encoded depth tile into z (pixels * spp values).
inline void decode_depth_tile(const std::vector<uint8_t>& bytes, uint32_t pixels, int spp, const uint8_t* pos_x,
                              const uint8_t* pos_y, float* z) {
  BitReader rd(bytes);
  const int p = int(rd.get(3)) + 1, r = int(rd.get(5));
  std::vector<DepthPlane> pl(static_cast<size_t>(p));
  for (auto& q : pl) {
    q.a = int32_t(uint32_t(rd.get(32)));
    q.gx = int32_t(uint32_t(rd.get(32)));
    q.gy = int32_t(uint32_t(rd.get(32)));
  }
  const int sb = log2_ceil(uint32_t(p));
  for (uint32_t i = 0; i < pixels * uint32_t(spp); ++i) {
    const uint32_t px = i / uint32_t(spp), s = i % uint32_t(spp);
    const uint64_t k = rd.get(sb);
    int64_t res = int64_t(rd.get(r));
    if (r > 0 && (res >> (r - 1) & 1)) res -= int64_t{1} << r;  // sign-extend
    const int64_t X = 256 * (px & 7u) + pos_x[s], Y = 256 * (px >> 3) + pos_y[s];
    const uint32_t u = uint32_t(pl[k < pl.size() ? k : 0].predict(X, Y) + res);
    std::memcpy(&z[i], &u, 4);
  }
}

// ---------------------------------------------------------------- colour

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
}  // namespace compression_detail

/// The encoded size of a colour tile with at most K distinct values per
/// pixel, in bits, or ~0 when some pixel has more than K. Per pixel:
/// ceil(log2 K) bits k - 1, k values of 8 bps bits, and when k > 1 an index
/// of ceil(log2 K) bits per sample (values in order of first appearance).
inline uint64_t color_tile_bits(const ColorTileIn& t, uint32_t K, uint32_t* max_k = nullptr) {
  const int ib = log2_ceil(K);
  uint64_t bits = 0;
  uint32_t mk = 0, first[8];
  for (uint32_t p = 0; p < t.pixels; ++p) {
    uint32_t k = 0;
    if (!compression_detail::pixel_palette(t, p, K, k, first, nullptr)) {
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

// ---------------------------------------------------------------- sizes

/// A tile's compressed form: its block-size class (0 = uncompressed) and the
/// bytes it occupies in memory (U >> class).
struct TileSize {
  int size_class = 0;
  uint64_t bytes = 0;
};

inline TileSize depth_tile_size(const DepthTileIn& t, const CompressionFormat& f) {
  const uint64_t U = uint64_t(t.pixels) * uint64_t(t.spp) * kDepthSampleBytes;
  const DepthFit fit = best_depth_fit(t, int(f.depth_planes));
  const int c = fit.ok ? size_class(ceil_div(fit.bits, uint64_t{8}), U, f) : 0;
  return {c, U >> c};
}

inline TileSize color_tile_size(const ColorTileIn& t, const CompressionFormat& f) {
  const uint64_t U = uint64_t(t.pixels) * uint64_t(t.spp) * t.bps;
  const uint64_t b = color_tile_bits(t, f.color_k);
  const int c = b == ~uint64_t{0} ? 0 : size_class(ceil_div(b, uint64_t{8}), U, f);
  return {c, U >> c};
}

}  // namespace ropsim
