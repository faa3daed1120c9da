#include "vectors.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstring>
#include <iterator>
#include <sstream>
#include <stdexcept>

#include "alpha_ref.h"
#include "depth.h"
#include "half.h"
#include "hilbert.h"
#include "opacity.h"
#include "random_hash.h"
#include "sample_patterns.h"
#include "sort_order.h"
#include "tracker.h"

namespace ropsim {

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
    sid &= uint32_t(low_mask(num.surface_id_bits));  // the surface-id register's width
    const uint32_t idx = alpha_ref_index(s, p, spp, num.hash_bits);
    out += fmt::format("{},{},{},{},{},{},{}\n", s, p, sid, spp, num.hash_bits, hex32(idx),
                       hex32(calc_alpha_ref_index(idx, sid, num.hash_bits)));
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

std::string join_hex_depths(const float* d, int spp) {
  std::string s;
  for (int i = 0; i < spp; ++i) s += (i ? ";" : "") + hexf(d[i]);
  return s;
}

std::string sorter_vectors(uint64_t count, VecRng& rng) {
  std::string out = "spp,surviving_hex,stored_depths_hex,order\n";
  for (uint64_t n = 0; n < count; ++n) {
    const int spp = n < 2 ? rng.directed_spp(64) : rng.spp();
    float d[64];
    for (int i = 0; i < spp; ++i) d[i] = n == 0 ? 1.0f : rng.depth();  // vector 0: all ties
    const uint64_t s = n < 2 ? low_mask(spp) : rng.mask(spp);
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

std::string opacity_vectors(uint64_t count, VecRng& rng, const Numerics& num) {
  std::string out = "alpha_bits,hash_bits,a_fixed_hex,ref_hex,pass\n";
  const int ab = num.alpha_bits, hb = num.hash_bits;
  const uint64_t a_max = uint64_t{1} << ab;
  const uint32_t r_max = uint32_t(low_mask(hb));
  uint64_t n = 0;
  auto emit = [&](uint64_t a, uint32_t ref) {
    out += fmt::format("{},{},{:09x},{},{}\n", ab, hb, a, hex32(ref), int(opacity_passes(a, ab, ref, hb)));
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
  std::string out = "order,x,y,d_hex\n";
  uint64_t n = 0;
  auto emit = [&](int k, uint32_t x, uint32_t y) {
    out += fmt::format("{},{},{},{}\n", k, x, y, hex64(hilbert_xy2d(1u << k, x, y)));
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

// --------------------------------------------------------------- hex format
// Each CSV column's place in a $readmemh word: its kind and bits per value.
enum class Col { kDec, kHex, kHexList, kDecList };
struct ColSpec {
  const char* name;
  Col kind;
  int bits;       ///< bits of one value (rounded up to whole hex digits)
  int count = 1;  ///< values of a list (missing ones, and "-", are 0)
};

const std::vector<ColSpec>& hex_layout(const std::string& unit) {
  static const std::vector<ColSpec> alpha = {
      {"sample_id", Col::kDec, 32}, {"pixel_id", Col::kDec, 64}, {"surface_id", Col::kDec, 32}, {"spp", Col::kDec, 8},
      {"hash_bits", Col::kDec, 8},  {"index", Col::kHex, 32},    {"ref", Col::kHex, 32}};
  static const std::vector<ColSpec> tracker = {{"spp", Col::kDec, 8},         {"surface_id_bits", Col::kDec, 8},
                                               {"covered_in", Col::kHex, 64}, {"surface_id_in", Col::kDec, 32},
                                               {"surviving", Col::kHex, 64},  {"new_surface", Col::kDec, 4},
                                               {"n", Col::kDec, 8},           {"surface_id_out", Col::kDec, 32},
                                               {"covered_out", Col::kHex, 64}};
  static const std::vector<ColSpec> sorter = {{"spp", Col::kDec, 8},
                                              {"surviving", Col::kHex, 64},
                                              {"stored_depths", Col::kHexList, 32, 64},
                                              {"order", Col::kDecList, 8, 64}};
  static const std::vector<ColSpec> depth = {{"spp", Col::kDec, 8},
                                             {"coverage", Col::kHex, 64},
                                             {"z0", Col::kHex, 32},
                                             {"dzdx", Col::kHex, 32},
                                             {"dzdy", Col::kHex, 32},
                                             {"stored_depths", Col::kHexList, 32, 64},
                                             {"sample_depths", Col::kHexList, 32, 64},
                                             {"pass", Col::kHex, 64}};
  static const std::vector<ColSpec> opacity = {{"alpha_bits", Col::kDec, 8},
                                               {"hash_bits", Col::kDec, 8},
                                               {"a_fixed", Col::kHex, 36},
                                               {"ref", Col::kHex, 32},
                                               {"pass", Col::kDec, 4}};
  static const std::vector<ColSpec> hilbert = {
      {"order", Col::kDec, 8}, {"x", Col::kDec, 32}, {"y", Col::kDec, 32}, {"d", Col::kHex, 64}};
  static const std::vector<ColSpec> half = {
      {"f32", Col::kHex, 32}, {"half", Col::kHex, 16}, {"half_in", Col::kHex, 16}, {"f32_out", Col::kHex, 32}};
  if (unit == "alpha-ref") return alpha;
  if (unit == "tracker") return tracker;
  if (unit == "sorter") return sorter;
  if (unit == "depth-test") return depth;
  if (unit == "opacity") return opacity;
  if (unit == "hilbert") return hilbert;
  return half;
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::istringstream in(s);
  for (std::string f; std::getline(in, f, sep);) out.push_back(f);
  if (!s.empty() && s.back() == sep) out.push_back("");
  return out;
}

/// The CSV rows of `unit` as $readmemh words: a comment block naming each
/// field's bits, then one line per vector, the first column in the most
/// significant digits; a list's element i at [lo + i * bits +: bits].
std::string csv_to_hex(const std::string& unit, const std::string& csv) {
  const auto& layout = hex_layout(unit);
  int total = 0;
  for (const ColSpec& c : layout) total += 4 * ((c.bits + 3) / 4) * c.count;
  std::string out = fmt::format("// ropsim vectors {}: one {}-bit word per vector ($readmemh), fields:\n", unit, total);
  int hi = total;
  for (const ColSpec& c : layout) {
    const int w = 4 * ((c.bits + 3) / 4);
    hi -= w * c.count;
    if (c.count == 1)
      out += fmt::format("//   [{}:{}] {}\n", hi + w - 1, hi, c.name);
    else
      out += fmt::format("//   [{}:{}] {}: {} x {} bits, element i at [{} + {} * i +: {}]\n", hi + w * c.count - 1, hi,
                         c.name, c.count, w, hi, w, w);
  }
  const auto lines = split(csv, '\n');
  for (size_t r = 1; r < lines.size(); ++r) {
    if (lines[r].empty()) continue;
    const auto cols = split(lines[r], ',');
    if (cols.size() != layout.size())
      throw std::logic_error("vectors: hex layout of " + unit + " does not fit its CSV");
    std::string word;
    for (size_t c = 0; c < layout.size(); ++c) {
      const ColSpec& spec = layout[c];
      const int digits = (spec.bits + 3) / 4;
      std::vector<std::string> vals = spec.count == 1 ? std::vector<std::string>{cols[c]} : split(cols[c], ';');
      vals.resize(size_t(spec.count));
      // A list's last element first: the word's most significant digits.
      for (int i = spec.count - 1; i >= 0; --i) {
        const std::string& v = vals[size_t(i)];
        uint64_t x = 0;
        if (!v.empty() && v != "-")
          x = std::stoull(v, nullptr, spec.kind == Col::kDec || spec.kind == Col::kDecList ? 10 : 16);
        word += fmt::format("{:0{}x}", x, digits);
      }
    }
    out += word + "\n";
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
  if (opt.spp != 0 && !is_valid_spp(opt.spp)) throw std::invalid_argument("spp must be 1, 2, 4, ..., 64");
  if (opt.hilbert_order < 0 || opt.hilbert_order > 16) throw std::invalid_argument("order must be in [1, 16]");
  if (opt.format != "csv" && opt.format != "hex") throw std::invalid_argument("format must be csv or hex");
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
    throw std::invalid_argument("unknown unit '" + unit + "' (known: " + known + ")");
  }
  return opt.format == "hex" ? csv_to_hex(unit, csv) : csv;
}

}  // namespace ropsim
