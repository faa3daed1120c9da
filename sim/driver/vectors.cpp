// Random RTL test vectors: each unit's rows from a seeded generator.
#include "sim/driver/vectors.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstring>
#include <iterator>
#include <sstream>
#include <stdexcept>

#include "rtl_models/algo/alpha_ref.h"
#include "rtl_models/algo/depth.h"
#include "rtl_models/algo/half.h"
#include "rtl_models/algo/hilbert.h"
#include "rtl_models/algo/opacity.h"
#include "rtl_models/algo/random_hash.h"
#include "rtl_models/algo/sort_order.h"
#include "rtl_models/algo/tracker.h"
#include "rtl_models/golden/golden_model.h"
#include "sim/driver/vector_rows.h"
#include "traces/raster/sample_patterns.h"
#include "util/errors.h"

namespace ropsim {

using namespace vector_rows;

namespace {

class VecRng {
 public:
  VecRng(uint64_t seed, int fixed_spp) : s_(mix64(seed ^ 0xC5C5C5C5ull)), fixed_spp_(fixed_spp) {}
  uint64_t u64() { return mix64(s_++); }
  uint32_t below(uint32_t n) { return uint32_t((u64() >> 32) * n >> 32); }
  /// The spp of a random vector: --spp when given, else 1..64 at random
  /// (the draw is made either way, so --spp changes no other field's value).
  int spp() {
    const int s = 1 << below(7);
    return fixed_spp_ ? fixed_spp_ : s;
  }
  /// A directed case's spp: --spp when given.
  int directed_spp(int spp) const { return fixed_spp_ ? fixed_spp_ : spp; }
  uint64_t mask(int spp) {
    uint64_t m = u64();
    switch (below(4)) {
      case 0:
        m &= u64();
        break;  // sparse
      case 1:
        m |= u64();
        break;  // dense
      case 2:
        m = ~0ull;
        break;  // full
      default:
        break;
    }
    return spp == 64 ? m : m & ((uint64_t{1} << spp) - 1);
  }
  float depth() {
    switch (below(4)) {
      case 0:
        return 1.0f;  // cleared
      case 1:
        return float(below(4)) * 0.25f;  // frequent ties
      default:
        return float(u64() >> 40) * 0x1p-24f;  // [0, 1)
    }
  }

 private:
  uint64_t s_;
  int fixed_spp_;
};

std::string alpha_ref_vectors(uint64_t count, VecRng& rng, const Numerics& num) {
  std::string out = kAlphaRefHeader;
  struct Case {
    uint32_t s;
    uint64_t p;
    uint32_t sid;
    uint32_t spp;
  };
  std::vector<Case> directed = {{0, 0, 0, 1},           {0, 1, 0, 1},
                                {0, 0, 1, 1},           {0, 5, 7, 1},
                                {0, 12345, 678, 1},     {63, (1ull << 26) - 1, 0xFFFFFFFFu, 64},
                                {0, 1ull << 26, 1, 64}, {15, 0xFFFFFFFull, 3, 16}};
  uint64_t n = 0;
  auto emit = [&](uint32_t s, uint64_t p, uint32_t sid, uint32_t spp) {
    sid &= uint32_t(low_mask(num.surface_id_bits));  // the surface-id register's width
    const uint32_t idx = alpha_ref_index(s, p, spp, num.hash_bits);
    out += alpha_ref_row(s, p, sid, spp, num.hash_bits, idx, calc_alpha_ref_index(idx, sid, num.hash_bits));
    ++n;
  };
  for (const auto& c : directed) {
    const uint32_t spp = uint32_t(rng.directed_spp(int(c.spp)));
    if (n < count) emit(c.s % spp, c.p, c.sid, spp);
  }
  while (n < count) {
    const uint32_t spp = uint32_t(rng.spp());
    const uint32_t sid = rng.below(2) ? rng.below(16) : uint32_t(rng.u64());
    emit(rng.below(spp), rng.u64() >> 38, sid, spp);
  }
  return out;
}

std::string tracker_vectors(uint64_t count, VecRng& rng, const Numerics& num) {
  std::string out = kTrackerHeader;
  uint64_t n = 0;
  auto emit = [&](int spp, uint64_t covered, uint32_t sid, uint64_t surviving) {
    const TrackerState in{covered, sid};
    TrackerState t = in;
    TrackResult r = track_surface(t, surviving, num.surface_id_bits);
    track_commit(t, surviving);
    out += tracker_row(spp, num.surface_id_bits, in, surviving, r, t);
    ++n;
  };
  const uint32_t sid_max = uint32_t(low_mask(num.surface_id_bits));
  // Directed cases (with --spp, their masks cut to that many samples).
  auto directed = [&](int spp, uint64_t covered, uint32_t sid, uint64_t surviving) {
    const int s = rng.directed_spp(spp);
    if (n < count) emit(s, covered & low_mask(s), sid & sid_max, surviving & low_mask(s));
  };
  directed(16, 0, 0, 0xFFFF);       // first fragment
  directed(16, 0x00FF, 3, 0xFF00);  // disjoint: same surface
  directed(16, 0x00FF, 3, 0x0180);  // overlap: new surface
  directed(64, ~0ull, sid_max, 1);  // surface id wraps
  directed(4, 0x5, 9, 0);           // nothing survives
  while (n < count) {
    const int spp = rng.spp();
    emit(spp, rng.mask(spp), uint32_t(rng.u64()) & sid_max, rng.mask(spp));
  }
  return out;
}

std::string sorter_vectors(uint64_t count, VecRng& rng) {
  std::string out = kSorterHeader;
  for (uint64_t n = 0; n < count; ++n) {
    const int spp = n < 2 ? rng.directed_spp(64) : rng.spp();
    float d[64];
    for (int i = 0; i < spp; ++i) d[i] = n == 0 ? 1.0f : rng.depth();  // vector 0: all ties
    const uint64_t s = n < 2 ? low_mask(spp) : rng.mask(spp);
    uint8_t order_ids[64];
    const int m = sort_by_stored_depth(d, s, order_ids);  // the golden model's sorter
    out += sorter_row(spp, s, d, order_ids, m);
  }
  return out;
}

std::string depth_test_vectors(uint64_t count, VecRng& rng) {
  std::string out = kDepthTestHeader;
  for (uint64_t n = 0; n < count; ++n) {
    const int spp = rng.spp();
    const auto pos = standard_sample_positions(spp);
    uint64_t cov = rng.mask(spp);
    if (!cov) cov = 1;
    float z0 = rng.depth(), dzdx = 0, dzdy = 0;
    if (rng.below(4)) {
      dzdx = (float(int32_t(rng.below(2001)) - 1000)) * 0x1p-12f;
      dzdy = (float(int32_t(rng.below(2001)) - 1000)) * 0x1p-12f;
    }
    float stored[64], z[64];
    for (int i = 0; i < spp; ++i) stored[i] = rng.below(3) ? rng.depth() : z0;  // ties with z0
    uint64_t pass = 0;
    for (int i = 0; i < spp; ++i)
      if (cov >> i & 1) {
        z[i] = plane_depth(z0, dzdx, dzdy, sample_offset(pos[i].x), sample_offset(pos[i].y));
        if (depth_passes(z[i], stored[i])) pass |= uint64_t{1} << i;
      }
    out += depth_test_row(spp, cov, z0, dzdx, dzdy, stored, z, pass);
  }
  return out;
}

std::string opacity_vectors(uint64_t count, VecRng& rng, const Numerics& num) {
  std::string out = kOpacityHeader;
  const int ab = num.alpha_bits, hb = num.hash_bits;
  const uint64_t a_max = uint64_t{1} << ab;
  const uint32_t r_max = uint32_t(low_mask(hb));
  uint64_t n = 0;
  auto emit = [&](uint64_t a, uint32_t ref) {
    out += opacity_row(ab, hb, a, ref, opacity_passes(a, ab, ref, hb));
    ++n;
  };
  // Directed: alpha 0 never passes, alpha 1 always, the ends of ref's range.
  for (uint64_t a : {uint64_t{0}, a_max, uint64_t{1}, a_max - 1})
    for (uint32_t ref : {0u, r_max, r_max >> 1})
      if (n < count) emit(a, ref);
  while (n < count) {
    uint64_t a = rng.u64() % (a_max + 1);
    uint32_t ref = uint32_t(rng.u64()) & r_max;
    if (rng.below(2)) {  // on or next to the threshold A / 2^ab = ref / 2^hb
      const uint64_t on = ab >= hb ? a >> (ab - hb) : a << (hb - ab);
      ref = uint32_t(std::min<uint64_t>(on, r_max) + rng.below(3) - 1) & r_max;
    }
    emit(a, ref);
  }
  return out;
}

std::string hilbert_vectors(uint64_t count, VecRng& rng, int order) {
  std::string out = kHilbertHeader;
  uint64_t n = 0;
  auto emit = [&](int k, uint32_t x, uint32_t y) {
    out += hilbert_row(k, x, y, hilbert_xy2d(1u << k, x, y));
    ++n;
  };
  // Directed: the 4 x 4 grid of hilbert.h's comment (order 2), then corners.
  if (order == 0 || order == 2)
    for (uint32_t y = 0; y < 4; ++y)
      for (uint32_t x = 0; x < 4; ++x)
        if (n < count) emit(2, x, y);
  while (n < count) {
    const int k = order ? order : 1 + int(rng.below(16));
    const uint32_t side = 1u << k;
    uint32_t x = rng.below(side), y = rng.below(side);
    if (rng.below(8) == 0) x = rng.below(2) ? side - 1 : 0;  // edges
    if (rng.below(8) == 0) y = rng.below(2) ? side - 1 : 0;
    emit(k, x, y);
  }
  return out;
}

float bits_float(uint32_t b) {
  float f;
  std::memcpy(&f, &b, 4);
  return f;
}

std::string half_vectors(uint64_t count, VecRng& rng) {
  std::string out = "f32_hex,half_hex,half_in_hex,f32_out_hex\n";
  uint64_t n = 0;
  auto emit = [&](uint32_t f, uint16_t h) {
    out += fmt::format("{},{:04x},{:04x},{}\n", hex32(f), float_to_half(bits_float(f)), h,
                       hex32(depth_bits(half_to_float(h))));
    ++n;
  };
  // Directed: zeros, the smallest subnormal and its halfway points, the
  // largest finite half and the first value that rounds to infinity,
  // infinities and NaNs, a tie to even in the normal range.
  const uint32_t fs[] = {0x00000000u, 0x80000000u, 0x33800000u, 0x33000000u, 0x33000001u, 0x477FE000u,
                         0x477FF000u, 0x477FEFFFu, 0x7F800000u, 0xFF800000u, 0x7FC00000u, 0x7F800001u,
                         0x3F801000u, 0x3F803000u, 0x38800000u, 0x387FFFFFu};
  const uint16_t hs[] = {0x0000, 0x8000, 0x0001, 0x03FF, 0x0400, 0x7BFF, 0x7C00, 0xFC00,
                         0x7E00, 0x7C01, 0x3C00, 0xBC00, 0x8001, 0x83FF, 0x3555, 0xFFFF};
  for (size_t i = 0; i < std::size(fs); ++i)
    if (n < count) emit(fs[i], hs[i]);
  while (n < count) {
    uint32_t f = uint32_t(rng.u64());
    // Most values in binary16's range (exponent 2^-25 .. 2^16), some anywhere.
    if (rng.below(4)) f = (f & 0x807FFFFFu) | ((102u + rng.below(42)) << 23);
    emit(f, uint16_t(rng.u64()));
  }
  return out;
}

}  // namespace

const std::vector<std::string>& vector_formats() {
  static const std::vector<std::string> f = {"csv", "hex"};
  return f;
}

const std::vector<std::string>& vector_units() {
  static const std::vector<std::string> u = {"alpha-ref", "tracker", "sorter", "depth-test",
                                             "opacity",   "hilbert", "half"};
  return u;
}

std::string make_vectors(const std::string& unit, uint64_t count, uint64_t seed, const Numerics& num,
                         const VectorOptions& opt) {
  if (opt.spp != 0 && !is_valid_spp(opt.spp)) throw VectorError("spp must be 1, 2, 4, ..., 64");
  if (opt.hilbert_order < 0 || opt.hilbert_order > 16) throw VectorError("order must be in [1, 16]");
  if (opt.format != "csv" && opt.format != "hex") throw VectorError("format must be csv or hex");
  VecRng rng(seed, opt.spp);
  std::string csv;
  if (unit == "alpha-ref") {
    csv = alpha_ref_vectors(count, rng, num);
  } else if (unit == "tracker") {
    csv = tracker_vectors(count, rng, num);
  } else if (unit == "sorter") {
    csv = sorter_vectors(count, rng);
  } else if (unit == "depth-test") {
    csv = depth_test_vectors(count, rng);
  } else if (unit == "opacity") {
    csv = opacity_vectors(count, rng, num);
  } else if (unit == "hilbert") {
    csv = hilbert_vectors(count, rng, opt.hilbert_order);
  } else if (unit == "half") {
    csv = half_vectors(count, rng);
  } else {
    std::string known;
    for (const auto& u : vector_units()) known += (known.empty() ? "" : ", ") + u;
    throw VectorError("unknown unit '" + unit + "' (known: " + known + ")");
  }
  return opt.format == "hex" ? csv_to_hex(unit, csv) : csv;
}

}  // namespace ropsim
