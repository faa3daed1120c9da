#include "vectors.h"

#include <fmt/format.h>

#include <stdexcept>

#include "alpha_ref.h"
#include "depth.h"
#include "random_hash.h"
#include "sample_patterns.h"
#include "sort_order.h"
#include "tracker.h"

namespace ropsim {

namespace {

class VecRng {
 public:
  explicit VecRng(uint64_t seed) : s_(mix64(seed ^ 0xC5C5C5C5ull)) {}
  uint64_t u64() { return mix64(s_++); }
  uint32_t below(uint32_t n) { return uint32_t((u64() >> 32) * n >> 32); }
  int spp() { return 1 << below(7); }
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
};

std::string hex32(uint32_t v) { return fmt::format("{:08x}", v); }
std::string hexf(float f) { return hex32(depth_bits(f)); }
std::string hex64(uint64_t v) { return fmt::format("{:016x}", v); }

std::string alpha_ref_vectors(uint64_t count, VecRng& rng, const Numerics& num) {
  std::string out = "sample_id,pixel_id,surface_id,spp,hash_bits,index_hex,ref_hex\n";
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
    const uint32_t idx = alpha_ref_index(s, p, spp, num.hash_bits);
    out += fmt::format("{},{},{},{},{},{},{}\n", s, p, sid, spp, num.hash_bits, hex32(idx),
                       hex32(calc_alpha_ref_index(idx, sid, num.hash_bits)));
    ++n;
  };
  for (const auto& c : directed)
    if (n < count) emit(c.s, c.p, c.sid, c.spp);
  while (n < count) {
    const uint32_t spp = uint32_t(rng.spp());
    const uint32_t sid = rng.below(2) ? rng.below(16) : uint32_t(rng.u64());
    emit(rng.below(spp), rng.u64() >> 38, sid, spp);
  }
  return out;
}

std::string tracker_vectors(uint64_t count, VecRng& rng, const Numerics& num) {
  std::string out =
      "spp,surface_id_bits,covered_in_hex,surface_id_in,surviving_hex,new_surface,n,surface_id_out,covered_out_hex\n";
  uint64_t n = 0;
  auto emit = [&](int spp, uint64_t covered, uint32_t sid, uint64_t surviving) {
    TrackerState t{covered, sid};
    TrackResult r = track_surface(t, surviving, num.surface_id_bits);
    track_commit(t, surviving);
    out += fmt::format("{},{},{},{},{},{},{},{},{}\n", spp, num.surface_id_bits, hex64(covered), sid, hex64(surviving),
                       int(r.new_surface), r.n, t.surface_id, hex64(t.covered));
    ++n;
  };
  const uint32_t sid_max = uint32_t(low_mask(num.surface_id_bits));
  if (n < count) emit(16, 0, 0, 0xFFFF);       // first fragment
  if (n < count) emit(16, 0x00FF, 3, 0xFF00);  // disjoint: same surface
  if (n < count) emit(16, 0x00FF, 3, 0x0180);  // overlap: new surface
  if (n < count) emit(64, ~0ull, sid_max, 1);  // surface id wraps
  if (n < count) emit(4, 0x5, 9, 0);           // nothing survives
  while (n < count) {
    const int spp = rng.spp();
    emit(spp, rng.mask(spp), uint32_t(rng.u64()) & sid_max, rng.mask(spp));
  }
  return out;
}

std::string join_hex_depths(const float* d, int spp) {
  std::string s;
  for (int i = 0; i < spp; ++i) s += (i ? ";" : "") + hexf(d[i]);
  return s;
}

std::string sorter_vectors(uint64_t count, VecRng& rng) {
  std::string out = "spp,surviving_hex,stored_depths_hex,order\n";
  for (uint64_t n = 0; n < count; ++n) {
    const int spp = n < 2 ? 64 : rng.spp();
    float d[64];
    for (int i = 0; i < spp; ++i) d[i] = n == 0 ? 1.0f : rng.depth();  // vector 0: all ties
    const uint64_t s = n < 2 ? ~0ull : rng.mask(spp);
    uint8_t order_ids[64];
    const int m = sort_by_stored_depth(d, s, order_ids);  // the golden model's sorter
    std::string order;
    for (int k = 0; k < m; ++k) order += (k ? ";" : "") + std::to_string(order_ids[k]);
    out += fmt::format("{},{},{},{}\n", spp, hex64(s), join_hex_depths(d, spp), order);
  }
  return out;
}

std::string depth_test_vectors(uint64_t count, VecRng& rng) {
  std::string out = "spp,coverage_hex,z0_hex,dzdx_hex,dzdy_hex,stored_depths_hex,sample_depths_hex,pass_hex\n";
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
    std::string zs;
    for (int i = 0; i < spp; ++i) {
      if (cov >> i & 1) {
        z[i] = plane_depth(z0, dzdx, dzdy, sample_offset(pos[i].x), sample_offset(pos[i].y));
        if (depth_passes(z[i], stored[i])) pass |= uint64_t{1} << i;
        zs += (i ? ";" : "") + hexf(z[i]);
      } else {
        zs += (i ? ";" : "") + std::string("-");
      }
    }
    out += fmt::format("{},{},{},{},{},{},{},{}\n", spp, hex64(cov), hexf(z0), hexf(dzdx), hexf(dzdy),
                       join_hex_depths(stored, spp), zs, hex64(pass));
  }
  return out;
}

}  // namespace

const std::vector<std::string>& vector_units() {
  static const std::vector<std::string> u = {"alpha-ref", "tracker", "sorter", "depth-test"};
  return u;
}

std::string make_vectors(const std::string& unit, uint64_t count, uint64_t seed, const Numerics& num) {
  VecRng rng(seed);
  if (unit == "alpha-ref") return alpha_ref_vectors(count, rng, num);
  if (unit == "tracker") return tracker_vectors(count, rng, num);
  if (unit == "sorter") return sorter_vectors(count, rng);
  if (unit == "depth-test") return depth_test_vectors(count, rng);
  throw std::invalid_argument("unknown unit '" + unit + "' (known: alpha-ref, tracker, sorter, depth-test)");
}

}  // namespace ropsim
