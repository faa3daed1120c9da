// The depth fit encoder (compression.depth_encoder = "fit", a design
// option): up to P plane equations fitted to a tile's stored depths in the
// integer domain of the binary32 bit pattern, a per-sample plane selector
// and a per-sample signed residual of r bits (docs/architecture.md
// "Surface compression").
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include "rtl_models/algo/bit_stream.h"
#include "rtl_models/algo/bits.h"
#include "rtl_models/algo/compression_format.h"
#include "rtl_models/algo/numerics.h"

namespace ropsim {

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

/// A depth tile's samples in the planes' domain: each sample's depth bit
/// pattern u and position X, Y (1/256 pixel from the tile's top-left
/// corner), computed once per tile for every fit the encoder tries.
struct DepthSamples {
  std::vector<int64_t> u;
  std::vector<int64_t> u16;  ///< u 2^16 - 2^15 (fit_depth_tile's compares)
  std::vector<int32_t> X, Y;
  std::vector<int32_t> sx, sy;  ///< [spp] the sample positions (X = 256 column + sx[s], Y = 256 row + sy[s])
  uint32_t pixels = 0;
  uint32_t spp = 0;
  DepthSamples() = default;
  explicit DepthSamples(const DepthTileIn& t) { assign(t); }
  /// Refills from t, keeping the buffers' storage.
  void assign(const DepthTileIn& t) {
    pixels = t.pixels;
    spp = uint32_t(t.spp);
    const uint32_t n = pixels * spp;
    u.resize(n);
    u16.resize(n);
    X.resize(n);
    Y.resize(n);
    sx.resize(spp);
    sy.resize(spp);
    for (uint32_t s = 0; s < spp; ++s) {
      sx[s] = t.pos_x[s];
      sy[s] = t.pos_y[s];
    }
    for (uint32_t p = 0, i = 0; p < pixels; ++p)
      for (uint32_t s = 0; s < spp; ++s, ++i) {
        uint32_t bits;
        std::memcpy(&bits, &t.z[i], 4);
        u[i] = int64_t(bits);
        u16[i] = int64_t(bits) * 65536 - 32768;
        X[i] = int32_t(256 * (p & 7u)) + sx[s];
        Y[i] = int32_t(256 * (p >> 3)) + sy[s];
      }
  }
  uint32_t size() const { return uint32_t(u.size()); }
  /// fit_depth_tile's working buffers, kept across the fits of a tile.
  mutable std::vector<uint8_t> un, hit_a, hit_b;
  mutable std::vector<int64_t> ck, st;
  mutable std::vector<int32_t> cy, wx, wy;
  mutable std::vector<int64_t> wu;
};

namespace compression_detail {

inline bool fits_i32(int64_t v) { return v >= INT32_MIN && v <= INT32_MAX; }
/// A residual within a width as one unsigned compare: -h <= res < span - h
/// (r bits: h = 2^(r-1), span = 2^r; r = 0: h = 0, span = 1, res == 0).
inline bool in_range(int64_t res, uint64_t h, uint64_t span) { return uint64_t(res + int64_t(h)) < span; }
/// The plane through sample a with gradients gx, gy (A chosen so that a is exact).
inline bool plane_through(const DepthSamples& t, uint32_t a, int64_t gx, int64_t gy, DepthPlane& pl) {
  if (!fits_i32(gx) || !fits_i32(gy)) return false;
  pl.gx = int32_t(gx);
  pl.gy = int32_t(gy);
  pl.a = 0;
  const int64_t A = t.u[a] - pl.predict(t.X[a], t.Y[a]);
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
inline DepthFit fit_depth_tile(const DepthSamples& t, int planes, int r) {
  using namespace compression_detail;
  const uint32_t n = t.size(), spp = t.spp;
  const int64_t* U = t.u.data();
  const int32_t* X = t.X.data();
  const int32_t* Y = t.Y.data();
  DepthFit f;
  f.r = r;
  f.sel.assign(n, 0xFF);
  uint8_t* sel = f.sel.data();
  // un[i] = 1 while sample i is unassigned.
  t.un.assign(n, 1);
  uint8_t* un = t.un.data();
  // The residual ranges of r bits (a plane's claim) and r + 1 bits (scoring a candidate).
  const uint64_t h0 = r ? uint64_t{1} << (r - 1) : 0, span0 = r ? uint64_t{1} << r : 1;
  const uint64_t h1 = uint64_t{1} << r, span1 = uint64_t{1} << (r + 1);
  uint32_t first = 0;
  t.hit_a.resize(n);
  t.hit_b.resize(n);
  uint8_t* hit_a = t.hit_a.data();
  uint8_t* hit_b = t.hit_b.data();
  t.st.resize(spp);
  t.wx.resize(n);
  t.wy.resize(n);
  t.wu.resize(n);
  int64_t* st = t.st.data();
  const int64_t* U16 = t.u16.data();
  const int32_t* SX = t.sx.data();
  const int32_t* SY = t.sy.data();
  // The unassigned samples that plane pl predicts within r bits (its
  // claim), as 0/1 per sample into h; returns their number. With v = gx X +
  // gy Y + 2^15, -h0 <= u - (A + floor(v / 2^16)) < span0 - h0 holds iff
  // 0 <= v - u 2^16 + (A + span0 - h0 - 1) 2^16 < span0 2^16: one unsigned
  // compare without a shift; gx X + gy Y split into a per-pixel and a
  // per-sample-index term, so the loop is additions (and vectorises).
  auto claim = [&](const DepthPlane& pl, uint8_t* h) {
    const int64_t base = (int64_t(pl.a) + int64_t(span0) - int64_t(h0) - 1) * 65536;
    const uint64_t lim = span0 * 65536;
    for (uint32_t s = 0; s < spp; ++s) st[s] = int64_t(pl.gx) * SX[s] + int64_t(pl.gy) * SY[s] + base;
    uint32_t c = 0;
    for (uint32_t p = first / spp; p < t.pixels; ++p) {
      const int64_t pt = int64_t(pl.gx) * (256 * int64_t(p & 7u)) + int64_t(pl.gy) * (256 * int64_t(p >> 3));
      const int64_t* u16 = U16 + size_t(p) * spp;
      const uint8_t* up = un + size_t(p) * spp;
      uint8_t* hp = h + size_t(p) * spp;
      uint8_t cp = 0;
      for (uint32_t s = 0; s < spp; ++s) {
        const uint8_t v = uint8_t(uint64_t(pt + st[s] - u16[s]) < lim) & up[s];
        hp[s] = v;
        cp = uint8_t(cp + v);
      }
      c += cp;
    }
    return c;
  };
  // The anchor's row and column (score_plane): at most 8 + rows - 1 pixels.
  t.ck.resize(size_t(8 + t.pixels / 8) * spp);
  t.cy.resize(t.ck.size());
  int64_t* ck = t.ck.data();
  int32_t* cy = t.cy.data();
  size_t m = 0;
  uint32_t most = 0, left = n;
  for (int k = 0; k < planes; ++k) {
    while (first < n && !un[first]) ++first;
    if (first == n) break;
    const uint32_t a = first, p = a / spp, s = a % spp;
    const int64_t ua = U[a];
    // A gradient along x (y): from the same sample of another pixel in the
    // anchor's row (column), the one whose line through the anchor meets
    // the most unassigned same-index samples of that row (column) within r
    // + 1 bits; ties to the nearest, then right (below). None: 0.
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
          if (!un[b]) continue;
          const int64_t du = U[b] - ua;
          // slope per 1/256 pixel with 16 fractional bits: du * 65536 / (256 * sign * d)
          const int64_t g = du * 256 / (sign * d);
          int score = 0;
          for (int q = 0; q < lim; ++q) {
            const uint32_t c = uint32_t(along_x ? row * 8 + q : q * 8 + col) * spp + s;
            const int64_t pred = ua + ((g * int64_t(256 * (q - at)) + (int64_t{1} << 15)) >> 16);
            score += un[c] & int(in_range(U[c] - pred, h1, span1));
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
    // The unassigned samples of the anchor's row and column, contiguous:
    // ck = gx X + 2^15 - u 2^16 and Y (score_plane).
    m = 0;
    auto add_pixel = [&](uint32_t pp) {
      for (uint32_t ss = 0; ss < spp; ++ss) {
        const uint32_t c = pp * spp + ss;
        ck[m] = gx * X[c] - U16[c];  // |gx| < 2^41 (or no plane): no overflow
        cy[m] = Y[c];
        m += un[c];
      }
    };
    for (int q = 0; q < 8; ++q) add_pixel(uint32_t(row * 8 + q));
    for (int q = 0; q < rows; ++q)
      if (q != row) add_pixel(uint32_t(q * 8 + col));
    // The score of the plane (gx, cgy) through the anchor: the samples of
    // the cross its prediction meets within r + 1 bits. With
    // v = gx X + gy Y + 2^15, -h1 <= u - (A + floor(v / 2^16)) < h1 holds iff
    // 0 <= v - (u - A - h1 + 1) 2^16 < 2 h1 2^16: one unsigned compare of
    // ck + gy Y + (A + h1 - 1) 2^16, without a shift (the loop vectorises).
    auto score_plane = [&](int64_t cgy) {
      DepthPlane q;
      if (!plane_through(t, a, gx, cgy, q)) return -1;
      const int64_t base = (int64_t(q.a) + int64_t(h1) - 1) * 65536;
      const uint64_t span = 2 * h1 * 65536;
      const int32_t qy = q.gy;
      int64_t sc = 0;  // as wide as the compare
      for (size_t c = 0; c < m; ++c) sc += uint64_t(ck[c] + int64_t(qy) * cy[c] + base) < span;
      return int(sc);
    };
    int64_t gy = best_gradient(false);
    int best_sc = score_plane(gy);
    {
      int64_t scored[64];  // candidates scored already (the same gradient scores the same)
      uint32_t n_scored = 0;
      for (uint32_t ss = 0; ss < spp; ++ss) {
        const uint32_t b = p * spp + ss;
        const int64_t dy = int64_t(Y[b]) - Y[a];
        if (!un[b] || dy == 0) continue;
        const int64_t rest = (U[b] - ua) * 65536 - gx * (int64_t(X[b]) - X[a]);
        const int64_t cgy = rest / dy;
        if (cgy == gy || std::find(scored, scored + n_scored, cgy) != scored + n_scored) continue;
        scored[n_scored++] = cgy;
        const int sc = score_plane(cgy);
        if (sc > best_sc) {
          best_sc = sc;
          gy = cgy;
        }
      }
    }
    DepthPlane pl;
    if (!plane_through(t, a, gx, gy, pl) && !plane_through(t, a, 0, 0, pl)) break;
    const uint32_t got = claim(pl, hit_a);
    const uint8_t* chosen = hit_a;
    uint32_t claimed = got;
    // Least-squares refit over the claimed samples (centred on the anchor);
    // the sums are exact (integers).
    if (got >= 3) {
      // The claimed samples' offsets from the anchor, contiguous.
      int32_t* wx = t.wx.data();
      int32_t* wy = t.wy.data();
      int64_t* wu = t.wu.data();
      uint32_t j = 0;
      for (uint32_t i = first; i < n; ++i) {
        wx[j] = X[i] - X[a];
        wy[j] = Y[i] - Y[a];
        wu[j] = U[i] - ua;
        j += hit_a[i];
      }
      int64_t sxx = 0, sxy = 0, syy = 0, sxu = 0, syu = 0;
      for (uint32_t q = 0; q < j; ++q) {
        const int64_t dx = wx[q], dy = wy[q];
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
      }
      for (uint32_t q = 0; q < j; ++q) {
        sxu += wx[q] * wu[q];
        syu += wy[q] * wu[q];
      }
      const double dxx = double(sxx), dxy = double(sxy), dyy = double(syy), dxu = double(sxu), dyu = double(syu);
      const double det = dxx * dyy - dxy * dxy;
      if (det > 0) {
        const double ggx = (dxu * dyy - dyu * dxy) / det, ggy = (dyu * dxx - dxu * dxy) / det;
        DepthPlane p2;
        if (std::fabs(ggx) < 2e4 && std::fabs(ggy) < 2e4 &&
            plane_through(t, a, std::llround(ggx * 65536.0), std::llround(ggy * 65536.0), p2)) {
          if (const uint32_t got2 = claim(p2, hit_b); got2 >= got) {
            pl = p2;
            chosen = hit_b;
            claimed = got2;
          }
        }
      }
    }
    const uint8_t kk = uint8_t(k);
    for (uint32_t i = first; i < n; ++i) {
      sel[i] = chosen[i] ? kk : sel[i];
      un[i] = uint8_t(un[i] ^ chosen[i]);  // chosen is within un
    }
    f.planes.push_back(pl);
    // Give up early when the planes left could not cover the rest even
    // claiming twice the most any plane claimed so far.
    most = std::max(most, claimed);
    left -= claimed;
    if (uint64_t(left) > uint64_t(planes - k - 1) * 2 * most) return f;  // not ok
  }
  if (left) return f;  // not ok
  f.ok = true;
  const uint64_t sel_bits = uint64_t(log2_ceil(uint32_t(f.planes.size())));
  f.bits = kDepthHeaderBits + kDepthPlaneBits * f.planes.size() + uint64_t(n) * (sel_bits + uint64_t(r));
  return f;
}
inline DepthFit fit_depth_tile(const DepthTileIn& t, int planes, int r) {
  return fit_depth_tile(DepthSamples(t), planes, r);
}

/// The encoder's fit: residual width 12 first (the most permissive; no fit
/// there and the tile is stored uncompressed), then 4, then 0, each tried
/// only while the wider one fitted; the fewest bits win (ties to the smaller r).
/// `enough`: stop trying narrower widths once a fit takes at most this many
/// bits (depth_tile_size: the smallest block; a narrower fit could not store
/// the tile in less).
inline DepthFit best_depth_fit(const DepthSamples& t, int planes, uint64_t enough = 0) {
  DepthFit best;
  for (int r : kDepthResidualWidths) {
    DepthFit f = fit_depth_tile(t, planes, r);
    if (!f.ok) break;
    if (!best.ok || f.bits <= best.bits) best = std::move(f);
    if (best.bits <= enough) break;
  }
  return best;
}
inline DepthFit best_depth_fit(const DepthTileIn& t, int planes) { return best_depth_fit(DepthSamples(t), planes); }

/// The encoded tile (docs/architecture.md): header (p - 1: 3 bits, r: 5
/// bits), p planes (A, Gx, Gy as 32-bit two's complement), then per sample
/// its selector (ceil(log2 p) bits) and residual (r bits, two's complement).
inline std::vector<uint8_t> encode_depth_fit(const DepthTileIn& in, const DepthFit& f) {
  const DepthSamples t(in);
  BitWriter w;
  w.put(f.planes.size() - 1, 3);
  w.put(uint64_t(f.r), 5);
  for (const DepthPlane& p : f.planes) {
    w.put(uint32_t(p.a), 32);
    w.put(uint32_t(p.gx), 32);
    w.put(uint32_t(p.gy), 32);
  }
  const int sb = log2_ceil(uint32_t(f.planes.size()));
  for (uint32_t i = 0; i < t.size(); ++i) {
    w.put(f.sel[i], sb);
    const int64_t res = t.u[i] - f.planes[f.sel[i]].predict(t.X[i], t.Y[i]);
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

}  // namespace ropsim
