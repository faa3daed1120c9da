#include "sim/driver/vector_rows.h"

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
#include "util/hex.h"

namespace ropsim::vector_rows {

std::string hexf(float f) { return hex32(depth_bits(f)); }

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

// Each CSV column's place in a $readmemh word: its kind and bits per value.
enum class Col { kDec, kHex, kHexList, kDecList };

namespace {

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

}  // namespace

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

}  // namespace ropsim::vector_rows
