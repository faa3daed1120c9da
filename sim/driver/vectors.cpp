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
#include "traces/raster/sample_patterns.h"
#include "util/errors.h"

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

// ------------------------------------------------------------- the rows
// One row of each unit's CSV, written once: the random vectors and the
// vectors captured from a trace both format their rows here.

const char* const kAlphaRefHeader = "sample_id,pixel_id,surface_id,spp,hash_bits,index_hex,ref_hex\n";
const char* const kTrackerHeader =
    "spp,surface_id_bits,covered_in_hex,surface_id_in,surviving_hex,new_surface,n,surface_id_out,covered_out_hex\n";
const char* const kSorterHeader = "spp,surviving_hex,stored_depths_hex,order\n";
const char* const kDepthTestHeader =
    "spp,coverage_hex,z0_hex,dzdx_hex,dzdy_hex,stored_depths_hex,sample_depths_hex,pass_hex\n";
const char* const kOpacityHeader = "alpha_bits,hash_bits,a_fixed_hex,ref_hex,pass\n";
const char* const kHilbertHeader = "order,x,y,d_hex\n";

std::string alpha_ref_row(uint32_t sample_id, uint64_t pixel_id, uint32_t surface_id, uint32_t spp, int hash_bits,
                          uint32_t index, uint32_t ref) {
  return fmt::format("{},{},{},{},{},{},{}\n", sample_id, pixel_id, surface_id, spp, hash_bits, hex32(index),
                     hex32(ref));
}

std::string tracker_row(int spp, int surface_id_bits, const TrackerState& in, uint64_t surviving, const TrackResult& r,
                        const TrackerState& out) {
  return fmt::format("{},{},{},{},{},{},{},{},{}\n", spp, surface_id_bits, hex64(in.covered), in.surface_id,
                     hex64(surviving), int(r.new_surface), r.n, out.surface_id, hex64(out.covered));
}

std::string join_hex_depths(const float* d, int spp) {
  std::string s;
  for (int i = 0; i < spp; ++i) s += (i ? ";" : "") + hexf(d[i]);
  return s;
}

std::string sorter_row(int spp, uint64_t surviving, const float* stored, const uint8_t* order, int m) {
  std::string o;
  for (int k = 0; k < m; ++k) o += (k ? ";" : "") + std::to_string(order[k]);
  return fmt::format("{},{},{},{}\n", spp, hex64(surviving), join_hex_depths(stored, spp), o);
}

/// z[i] is read for the covered samples only (the others are "-").
std::string depth_test_row(int spp, uint64_t coverage, float z0, float dzdx, float dzdy, const float* stored,
                           const float* z, uint64_t pass) {
  std::string zs;
  for (int i = 0; i < spp; ++i) zs += (i ? ";" : "") + (coverage >> i & 1 ? hexf(z[i]) : std::string("-"));
  return fmt::format("{},{},{},{},{},{},{},{}\n", spp, hex64(coverage), hexf(z0), hexf(dzdx), hexf(dzdy),
                     join_hex_depths(stored, spp), zs, hex64(pass));
}

std::string opacity_row(int alpha_bits, int hash_bits, uint64_t a_fixed, uint32_t ref, bool pass) {
  return fmt::format("{},{},{:09x},{},{}\n", alpha_bits, hash_bits, a_fixed, hex32(ref), int(pass));
}

std::string hilbert_row(int order, uint32_t x, uint32_t y, uint64_t d) {
  return fmt::format("{},{},{},{}\n", order, x, y, hex64(d));
}

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

/// The comment block that opens unit's hex file: the word width and each
/// field's bits.
std::string hex_comment(const std::string& unit) {
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
  return out;
}

/// One CSV row (no newline) of unit as its $readmemh word: the first column
/// in the most significant digits; a list's element i at [lo + i * bits +: bits].
std::string hex_word(const std::string& unit, const std::string& row) {
  const auto& layout = hex_layout(unit);
  const auto cols = split(row, ',');
  if (cols.size() != layout.size()) throw InternalError("vectors: hex layout of " + unit + " does not fit its CSV");
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
  return word;
}

/// The CSV rows of `unit` as $readmemh words: the comment block, then one
/// line per vector.
std::string csv_to_hex(const std::string& unit, const std::string& csv) {
  std::string out = hex_comment(unit);
  const auto lines = split(csv, '\n');
  for (size_t r = 1; r < lines.size(); ++r)
    if (!lines[r].empty()) out += hex_word(unit, lines[r]) + "\n";
  return out;
}

// ------------------------------------------------------ vectors from a trace

/// Formats each captured call of one unit as its row (or hex word) and
/// hands the text to the sink in pieces of about a megabyte.
class VectorCapture : public RopObserver {
 public:
  VectorCapture(const std::string& unit, const TraceHeader& h, const TraceVectorRequest& req,
                const std::function<void(std::string_view)>& write)
      : unit_(unit), spp_(h.spp), req_(req), hex_(req.format == "hex"), write_(write) {}

  void depth_tested(const FragWork& w) override {
    if (unit_ != "depth-test" || !keep(w)) return;
    const Fragment& f = *w.f;
    emit(depth_test_row(spp_, w.covered, f.z0, f.dzdx, f.dzdy, w.px.depth, w.z, w.survivors));
  }
  void tracked(const FragWork& w, const TrackerState& before, int surface_id_bits) override {
    if (unit_ == "tracker" && keep(w))
      emit(tracker_row(spp_, surface_id_bits, before, w.survivors, w.lk.track, *w.px.tracker));
  }
  void sorted(const FragWork& w) override {
    if (unit_ == "sorter" && keep(w)) emit(sorter_row(spp_, w.survivors, w.px.depth, w.lk.order, int(w.m)));
  }
  void referenced(const FragWork& w, uint32_t hilbert_n, uint64_t pixel_id, int hash_bits) override {
    if (!keep(w)) return;
    if (unit_ == "hilbert") emit(hilbert_row(__builtin_ctz(hilbert_n), w.f->x, w.f->y, pixel_id));
    if (unit_ != "alpha-ref") return;
    for (uint32_t j = 0; j < w.m; ++j) {
      const uint32_t sample_id = w.lk.track.n + j;  // the running index of LK Fig. 7 line 11
      emit(alpha_ref_row(sample_id, pixel_id, w.lk.track.surface_id, uint32_t(spp_), hash_bits,
                         alpha_ref_index(sample_id, pixel_id, uint32_t(spp_), hash_bits), w.lk.ref[j]));
    }
  }
  void opacity_tested(const FragWork& w, uint64_t a_fixed, int alpha_bits, uint32_t ref, int hash_bits,
                      bool passed) override {
    if (unit_ == "opacity" && keep(w)) emit(opacity_row(alpha_bits, hash_bits, a_fixed, ref, passed));
  }

  uint64_t rows() const { return rows_; }
  void start() { buf_ = hex_ ? hex_comment(unit_) : header_of(unit_); }
  void finish() {
    if (!buf_.empty()) write_(buf_);
    buf_.clear();
  }

 private:
  static std::string header_of(const std::string& unit) {
    if (unit == "alpha-ref") return kAlphaRefHeader;
    if (unit == "tracker") return kTrackerHeader;
    if (unit == "sorter") return kSorterHeader;
    if (unit == "depth-test") return kDepthTestHeader;
    if (unit == "opacity") return kOpacityHeader;
    return kHilbertHeader;
  }
  bool keep(const FragWork& w) const {
    const Fragment& f = *w.f;
    if (req_.draw && f.draw_id != *req_.draw) return false;
    if (const auto& b = req_.window) return f.x >= b->x0 && f.x <= b->x1 && f.y >= b->y0 && f.y <= b->y1;
    return true;
  }
  void emit(const std::string& row) {
    ++rows_;
    if (hex_)
      buf_ += hex_word(unit_, row.substr(0, row.size() - 1)) + "\n";
    else
      buf_ += row;
    if (buf_.size() >= (size_t{1} << 20)) finish();
  }
  std::string unit_;
  int spp_;
  const TraceVectorRequest& req_;
  bool hex_;
  const std::function<void(std::string_view)>& write_;
  std::string buf_;
  uint64_t rows_ = 0;
};

/// Does method m's ROP call unit's rule? Empty if so, else why not.
std::string calls_unit(Method m, const std::string& unit) {
  const MethodTraits& t = traits(selection_of(m));
  const char* name = to_string(m);
  if (!traits(m).pipeline) return std::string("the ") + name + " method has no ROP pipeline";
  if (unit == "depth-test" && m == Method::kSlab)
    return "slab has no per-sample depth test (its layers hold the depth)";
  if (unit == "depth-test" && m == Method::kBlend)
    return "blend tests depth with each draw's own function; the depth-test unit's rule (rop_depth_compare) is "
           "LEQUAL";
  if ((unit == "tracker" && !t.tracker) || (unit == "sorter" && !t.sorter) ||
      ((unit == "alpha-ref" || unit == "hilbert") && selection_of(m) != Method::kLk) ||
      (unit == "opacity" && selection_of(m) != Method::kLk && m != Method::kNaive))
    return std::string(name) + " never calls the " + unit + " unit (lk and its variants do" +
           (unit == "opacity" ? ", and naive" : "") + ")";
  return "";
}

}  // namespace

const std::vector<std::string>& trace_vector_units() {
  static const std::vector<std::string> u = {"alpha-ref", "tracker", "sorter", "depth-test", "opacity", "hilbert"};
  return u;
}

uint64_t make_trace_vectors(const std::string& unit, const TraceVectorRequest& req,
                            const std::function<void(std::string_view)>& write) {
  const auto& units = trace_vector_units();
  if (std::find(units.begin(), units.end(), unit) == units.end()) {
    std::string known;
    for (const auto& u : units) known += (known.empty() ? "" : ", ") + u;
    throw VectorError("--trace captures the calls of " + known + ", not " + unit);
  }
  if (req.format != "csv" && req.format != "hex") throw VectorError("format must be csv or hex");
  if (const std::string why = calls_unit(req.method.method, unit); !why.empty())
    throw VectorError(unit + " vectors of " + to_string(req.method.method) + ": " + why);
  if (const auto& b = req.window; b && (b->x0 > b->x1 || b->y0 > b->y1))
    throw VectorError("--window: x0 > x1 or y0 > y1");
  auto src = open_fragments(req.input);
  const TraceHeader h = src->header();
  if (unit == "depth-test") {
    // The depth-test vectors hold a plane and the standard sample positions.
    if (h.depth_mode != DepthMode::kPlane)
      throw VectorError(req.input.describe() +
                        ": the trace stores per-sample depths; depth-test vectors take a plane (z0, dzdx, dzdy)");
    const auto standard = standard_sample_positions(h.spp);
    for (int i = 0; i < h.spp; ++i)
      if (h.positions[size_t(i)].x != standard[size_t(i)].x || h.positions[size_t(i)].y != standard[size_t(i)].y)
        throw VectorError(req.input.describe() + ": sample " + std::to_string(i) +
                          "'s position is not the standard one of " + std::to_string(h.spp) +
                          " spp, which the depth-test vectors assume");
  }
  StochasticModel model(h, req.method, 1);
  VectorCapture capture(unit, h, req, write);
  model.set_rop_observer(&capture);
  capture.start();
  std::vector<Fragment> batch(4096);
  for (int pass = 0; pass < model.passes(); ++pass) {
    if (pass > 0) src = open_fragments(req.input);  // every pass replays the input
    model.begin_pass(pass);
    for (;;) {
      size_t n = 0;
      while (n < batch.size() && src->next(batch[n])) ++n;
      if (n == 0) break;
      model.draw_batch(batch.data(), n);
    }
  }
  capture.finish();
  return capture.rows();
}

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
