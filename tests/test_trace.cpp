// Trace format v1 (docs/trace-format.md): writer -> reader round trips for every
// header combination, streaming memory, and the reader's refusal of every kind
// of bad input with a one-line TraceError naming the file and the record.
//
// Bad traces are built with an encoder written here from the specification (not
// with TraceWriter, which validates), so these tests also check that the writer
// produces exactly the bytes the specification describes.
#include <gtest/gtest.h>
#include <unistd.h>
#include <xxhash.h>
#include <zstd.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <optional>
#include <random>
#include <regex>
#include <set>
#include <string>
#include <tuple>
#include <unordered_set>
#include <vector>

#include "rtl_models/algo/depth.h"
#include "tests/compare_util.h"
#include "traces/format/trace.h"
#include "traces/format/utf8.h"
#include "traces/raster/sample_patterns.h"

namespace fs = std::filesystem;
using namespace ropsim;

namespace ropsim {  // readable parameter names in test listings (found by ADL)
static void PrintTo(DepthMode m, std::ostream* os) { *os << to_string(m); }
static void PrintTo(ColorFormat c, std::ostream* os) { *os << to_string(c); }
static void PrintTo(Compression c, std::ostream* os) { *os << to_string(c); }
}  // namespace ropsim

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr int kSpps[] = {1, 2, 4, 8, 16, 32, 64};

// ------------------------------------------------------------------ helpers

/// A fresh directory under the system temp directory, removed with its contents.
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = std::string("ropsim-test-trace-") + std::to_string(::getpid()) + "-" +
                       (info ? std::string(info->test_suite_name()) + "-" + info->name() : "x");
    for (char& c : name)
      if (c == '/') c = '_';
    dir_ = fs::temp_directory_path() / name;
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string path(const std::string& file) const { return (dir_ / file).string(); }
  const fs::path& dir() const { return dir_; }

 private:
  fs::path dir_;
};

uint32_t bits(float f) {
  uint32_t b;
  std::memcpy(&b, &f, 4);
  return b;
}

std::string hexbits(float f) {
  char s[32];
  std::snprintf(s, sizeof s, "%g (0x%08x)", double(f), bits(f));
  return s;
}

uint64_t spp_mask(int spp) { return spp == 64 ? ~uint64_t{0} : (uint64_t{1} << spp) - 1; }

void write_file(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  ASSERT_TRUE(f.good()) << "cannot write " << path;
}

std::vector<uint8_t> read_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

/// VmRSS of this process in bytes, from /proc/self/status (0 if unknown).
size_t current_rss_bytes() {
  std::ifstream f("/proc/self/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("VmRSS:", 0) == 0) return size_t(std::stoull(line.substr(6))) * 1024;
  return 0;
}

// ------------------------------------------------------------------ an encoder from the specification

void put8(std::vector<uint8_t>& o, uint8_t v) { o.push_back(v); }
void put16(std::vector<uint8_t>& o, uint16_t v) {
  for (int i = 0; i < 2; ++i) o.push_back(uint8_t(v >> (8 * i)));
}
void put32(std::vector<uint8_t>& o, uint32_t v) {
  for (int i = 0; i < 4; ++i) o.push_back(uint8_t(v >> (8 * i)));
}
void put64(std::vector<uint8_t>& o, uint64_t v) {
  for (int i = 0; i < 8; ++i) o.push_back(uint8_t(v >> (8 * i)));
}
void putf(std::vector<uint8_t>& o, float f) { put32(o, bits(f)); }

/// Header bytes (fixed 48-byte part, 2 * spp position bytes, scene name,
/// then with `check` the header check: the XXH3-64 of the bytes before it);
/// with `count`, the fragment count recorded in bytes 42..47 (count + 1).
std::vector<uint8_t> encode_header_with(const TraceHeader& h, std::optional<uint64_t> count, bool check) {
  std::vector<uint8_t> o;
  for (char c : kTraceMagic) o.push_back(uint8_t(c));             // 0: magic
  put16(o, kTraceVersion);                                        // 8: version
  put16(o, uint16_t((h.checksummed ? 1 : 0) | (check ? 2 : 0)));  // 10: flags (bit 0: checksummed, 1: header check)
  put32(o, h.width);                                              // 12
  put32(o, h.height);                                             // 16
  put8(o, uint8_t(h.spp));                                        // 20
  put8(o, uint8_t(h.depth_mode));                                 // 21
  put8(o, uint8_t(h.color_format));                               // 22
  put8(o, uint8_t(h.compression));                                // 23
  for (float c : h.clear_color) putf(o, c);                       // 24, 28, 32
  putf(o, h.clear_depth);                                         // 36
  put16(o, uint16_t(h.scene_name.size()));                        // 40
  for (int i = 0; i < 6; ++i) put8(o, count ? uint8_t((*count + 1) >> (8 * i)) : 0);  // 42: fragments + 1, or 0
  EXPECT_EQ(o.size(), 48u);
  for (int i = 0; i < h.spp; ++i) {
    put8(o, h.positions[i].x);
    put8(o, h.positions[i].y);
  }
  o.insert(o.end(), h.scene_name.begin(), h.scene_name.end());
  if (check) put64(o, XXH3_64bits(o.data(), o.size()));
  return o;
}

/// The header as TraceWriter writes it: checked when the payload is checksummed.
std::vector<uint8_t> encode_header(const TraceHeader& h, std::optional<uint64_t> count = std::nullopt) {
  return encode_header_with(h, count, h.checksummed);
}

/// One fragment record, without any validation.
void encode_fragment(std::vector<uint8_t>& o, const TraceHeader& h, const Fragment& f) {
  put8(o, kTagFragment);
  put32(o, f.draw_id);
  put32(o, f.prim_id);
  put16(o, f.x);
  put16(o, f.y);
  for (int i = 0; i < (h.spp + 7) / 8; ++i) put8(o, uint8_t(f.coverage >> (8 * i)));
  if (h.depth_mode == DepthMode::kPlane) {
    putf(o, f.z0);
    putf(o, f.dzdx);
    putf(o, f.dzdy);
  } else {
    for (int i = 0; i < 64; ++i)
      if (f.coverage >> i & 1) putf(o, f.z[i]);
  }
  if (h.color_format == ColorFormat::kRgbF32) {
    for (float c : f.rgb) putf(o, c);
  } else {
    for (float c : f.rgb) put8(o, uint8_t(std::lround(std::min(1.0f, std::max(0.0f, c)) * 255.0f)));
  }
  putf(o, f.alpha);
}

void encode_end(std::vector<uint8_t>& o, uint64_t count) {
  put8(o, kTagEnd);
  put64(o, count);
}

std::vector<uint8_t> zstd_compress(const std::vector<uint8_t>& payload) {
  std::vector<uint8_t> out(ZSTD_compressBound(payload.size()));
  size_t n = ZSTD_compress(out.data(), out.size(), payload.data(), payload.size(), 3);
  EXPECT_FALSE(ZSTD_isError(n)) << ZSTD_getErrorName(n);
  out.resize(ZSTD_isError(n) ? 0 : n);
  return out;
}

/// header + (compressed) payload, as the header's compression field says.
std::vector<uint8_t> assemble(const TraceHeader& h, const std::vector<uint8_t>& payload,
                              std::optional<uint64_t> count = std::nullopt) {
  std::vector<uint8_t> o = encode_header(h, count);
  std::vector<uint8_t> p = h.compression == Compression::kZstd ? zstd_compress(payload) : payload;
  o.insert(o.end(), p.begin(), p.end());
  return o;
}

// ------------------------------------------------------------------ test data

TraceHeader make_header(int spp, DepthMode d, ColorFormat c, Compression z, uint32_t w = 97, uint32_t hgt = 53) {
  TraceHeader h;
  h.width = w;
  h.height = hgt;
  h.spp = spp;
  h.depth_mode = d;
  h.color_format = c;
  h.compression = z;
  h.clear_color = {0.25f, 0.5f, 2.0f};
  h.clear_depth = 0.75f;
  h.positions = standard_sample_positions(spp);
  h.scene_name = "round-trip \xc3\xbc scene";
  h.checksummed = false;  // the record-by-record layout; checksummed traces: make_ck_header()
  return h;
}

/// Deterministic valid fragments exercising corners, full and single-sample
/// masks, extreme ids and depths, then random ones.
std::vector<Fragment> make_fragments(const TraceHeader& h, size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  const bool unorm = h.color_format == ColorFormat::kRgbUnorm8;
  std::vector<Fragment> out;
  for (size_t i = 0; i < n; ++i) {
    Fragment f;
    f.draw_id = i == 1 ? 0xFFFFFFFFu : uint32_t(rng());
    f.prim_id = i == 1 ? 0xFFFFFFFFu : uint32_t(rng());
    f.x = uint16_t(i == 1 ? h.width - 1 : i == 2 ? 0 : rng() % h.width);
    f.y = uint16_t(i == 1 ? h.height - 1 : i == 2 ? 0 : rng() % h.height);
    switch (i) {
      case 0:
        f.coverage = spp_mask(h.spp);
        break;  // full
      case 1:
        f.coverage = uint64_t{1} << (h.spp - 1);
        break;  // highest sample only
      case 2:
        f.coverage = 1;
        break;  // sample 0 only
      default: {
        f.coverage = rng() & spp_mask(h.spp);
        if (!f.coverage) f.coverage = 1;
      }
    }
    f.z0 = i == 0 ? 0.0f : (unit(rng) * 4.0f - 2.0f);  // the plane itself may leave [0, 1]
    f.dzdx = i == 1 ? -1e30f : (unit(rng) - 0.5f) * 0.01f;
    f.dzdy = i == 1 ? 3e38f : (unit(rng) - 0.5f) * 0.01f;
    for (int s = 0; s < 64; ++s) f.z[s] = s % 7 == 0 ? 1.0f : s % 11 == 0 ? 0.0f : unit(rng);
    for (float& c : f.rgb) c = unorm ? unit(rng) : unit(rng) * 8.0f;  // f32 colour may exceed 1 (HDR)
    if (i == 0) f.rgb = {0.0f, 1.0f, unorm ? 0.5f : 1e6f};
    f.alpha = i == 0 ? 0.0f : i == 1 ? 1.0f : unit(rng);
    out.push_back(f);
  }
  return out;
}

Fragment one_valid_fragment(const TraceHeader& h) {
  Fragment f;
  f.draw_id = 3;
  f.prim_id = 9;
  f.x = uint16_t(h.width / 2);
  f.y = uint16_t(h.height / 2);
  f.coverage = spp_mask(h.spp);
  f.z0 = 0.5f;
  f.dzdx = 0.01f;
  f.dzdy = -0.02f;
  f.z.fill(0.5f);
  f.rgb = {0.2f, 0.4f, 0.6f};
  f.alpha = 0.5f;
  return f;
}

/// Reads the whole trace; returns the message of the TraceError it throws, or
/// "" (plus a test failure) when it throws nothing or something else.
std::string read_all_error(const std::string& path) {
  try {
    TraceReader r(path);
    Fragment f;
    while (r.next(f)) {
    }
    ADD_FAILURE() << path << ": expected a TraceError, but the whole trace was read (" << r.records_read()
                  << " fragments)";
  } catch (const TraceError& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << path << ": expected a TraceError, got another exception: " << e.what();
  }
  return "";
}

/// The error is one line, names the file, names record N (N < 0: names no
/// record) and contains `needle`.
void expect_trace_error(const std::string& path, long long record, const std::string& needle,
                        const std::string& context) {
  SCOPED_TRACE(context);
  const std::string msg = read_all_error(path);
  if (msg.empty()) return;
  EXPECT_EQ(msg.find('\n'), std::string::npos) << "error is not one line: " << msg;
  EXPECT_EQ(msg.find('\r'), std::string::npos) << "error is not one line: " << msg;
  EXPECT_EQ(msg.rfind(path, 0), 0u) << "error does not start with the file path " << path << ": " << msg;
  if (record >= 0)
    EXPECT_NE(msg.find(": record " + std::to_string(record) + ": "), std::string::npos)
        << "error does not name record " << record << ": " << msg;
  else
    EXPECT_EQ(msg.find("record "), std::string::npos) << "a header error names a record: " << msg;
  EXPECT_NE(msg.find(needle), std::string::npos) << "error lacks \"" << needle << "\": " << msg;
}

/// Record index named in a "...: record N: ..." message, or -1.
long long record_in(const std::string& msg) {
  const auto p = msg.find(": record ");
  if (p == std::string::npos) return -1;
  return std::atoll(msg.c_str() + p + 9);
}

// ------------------------------------------------------------------ round trips

using Combo = std::tuple<DepthMode, ColorFormat, Compression, int, bool>;  // bool: checksummed

class RoundTrip : public ::testing::TestWithParam<Combo> {};

TEST_P(RoundTrip, HeaderAndEveryFragmentFieldSurvive) {
  const auto [depth, colour, comp, spp, checksummed] = GetParam();
  TempDir tmp;
  const std::string path = tmp.path("rt.trace");
  TraceHeader h = make_header(spp, depth, colour, comp);
  h.checksummed = checksummed;
  // Positions other than the standard ones must survive too.
  for (int i = 0; i < spp; ++i) h.positions[i] = SamplePos{uint8_t(i * 37 + 5), uint8_t(255 - i * 3)};
  const std::vector<Fragment> frags = make_fragments(h, 300, 1000 + spp);
  uint64_t expect_raw = 9;
  {
    TraceWriter w(path, h);
    for (const Fragment& f : frags) {
      w.write(f);
      expect_raw += fragment_record_bytes(h, __builtin_popcountll(f.coverage));
    }
    EXPECT_EQ(w.fragments(), frags.size());
    w.finish();
    EXPECT_EQ(w.raw_bytes(), expect_raw) << "writer's raw byte count disagrees with fragment_record_bytes";
  }
  ASSERT_TRUE(fs::exists(path)) << "finish() did not create " << path;
  for (const auto& e : fs::directory_iterator(fs::path(path).parent_path()))
    EXPECT_NE(e.path().filename().string()[0], '.') << "finish() left " << e.path();

  TraceReader r(path);
  const TraceHeader& g = r.header();
  EXPECT_EQ(g.width, h.width);
  EXPECT_EQ(g.height, h.height);
  EXPECT_EQ(g.spp, h.spp);
  EXPECT_EQ(g.depth_mode, h.depth_mode);
  EXPECT_EQ(g.color_format, h.color_format);
  EXPECT_EQ(g.compression, h.compression);
  EXPECT_EQ(g.checksummed, h.checksummed);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(bits(g.clear_color[i]), bits(h.clear_color[i])) << "clear colour channel " << i;
  EXPECT_EQ(bits(g.clear_depth), bits(h.clear_depth));
  EXPECT_EQ(g.scene_name, h.scene_name);
  for (int i = 0; i < spp; ++i) {
    EXPECT_EQ(g.positions[i].x, h.positions[i].x) << "position x of sample " << i;
    EXPECT_EQ(g.positions[i].y, h.positions[i].y) << "position y of sample " << i;
  }

  Fragment f;
  size_t n = 0;
  while (r.next(f)) {
    ASSERT_LT(n, frags.size()) << "reader returned more fragments than were written";
    const Fragment& e = frags[n];
    SCOPED_TRACE("fragment " + std::to_string(n));
    EXPECT_EQ(f.draw_id, e.draw_id);
    EXPECT_EQ(f.prim_id, e.prim_id);
    EXPECT_EQ(f.x, e.x);
    EXPECT_EQ(f.y, e.y);
    EXPECT_EQ(f.coverage, e.coverage);
    if (depth == DepthMode::kPlane) {
      EXPECT_EQ(bits(f.z0), bits(e.z0)) << hexbits(f.z0) << " vs " << hexbits(e.z0);
      EXPECT_EQ(bits(f.dzdx), bits(e.dzdx)) << hexbits(f.dzdx) << " vs " << hexbits(e.dzdx);
      EXPECT_EQ(bits(f.dzdy), bits(e.dzdy)) << hexbits(f.dzdy) << " vs " << hexbits(e.dzdy);
    } else {
      for (int s = 0; s < 64; ++s) {
        if (e.coverage >> s & 1) {
          EXPECT_EQ(bits(f.z[s]), bits(e.z[s]))
              << "depth of sample " << s << ": " << hexbits(f.z[s]) << " vs " << hexbits(e.z[s]);
        }
      }
    }
    for (int c = 0; c < 3; ++c) {
      const float want = colour == ColorFormat::kRgbF32 ? e.rgb[c] : float(std::lround(e.rgb[c] * 255.0f)) / 255.0f;
      EXPECT_EQ(bits(f.rgb[c]), bits(want)) << "colour channel " << c << ": " << hexbits(f.rgb[c]) << " vs "
                                            << hexbits(want) << " (written " << e.rgb[c] << ")";
    }
    EXPECT_EQ(bits(f.alpha), bits(e.alpha)) << hexbits(f.alpha) << " vs " << hexbits(e.alpha);
    ++n;
  }
  EXPECT_EQ(n, frags.size()) << "reader returned fewer fragments than were written";
  EXPECT_EQ(r.records_read(), frags.size());
  EXPECT_EQ(r.payload_bytes(), expect_raw) << "payload size differs from the sum of fragment_record_bytes + 9";
  EXPECT_FALSE(r.next(f)) << "next() after the end record must keep returning false";
}

std::string combo_name(const ::testing::TestParamInfo<Combo>& info) {
  const auto [d, c, z, spp, ck] = info.param;
  std::string s = std::string(d == DepthMode::kPlane ? "Plane" : "PerSample") +
                  (c == ColorFormat::kRgbF32 ? "F32" : "Unorm8") + (z == Compression::kZstd ? "Zstd" : "Raw") +
                  std::to_string(spp) + "spp" + (ck ? "Checksummed" : "");
  return s;
}

INSTANTIATE_TEST_SUITE_P(AllCombinations, RoundTrip,
                         ::testing::Combine(::testing::Values(DepthMode::kPlane, DepthMode::kPerSample),
                                            ::testing::Values(ColorFormat::kRgbF32, ColorFormat::kRgbUnorm8),
                                            ::testing::Values(Compression::kZstd, Compression::kNone),
                                            ::testing::ValuesIn(kSpps), ::testing::Bool()),
                         combo_name);

TEST(TraceFormat, WriterBytesMatchTheSpecification) {
  // An uncompressed trace is exactly header + records + end record, byte for
  // byte as docs/trace-format.md describes (the encoder in this file).
  TempDir tmp;
  for (DepthMode d : {DepthMode::kPlane, DepthMode::kPerSample})
    for (ColorFormat c : {ColorFormat::kRgbF32, ColorFormat::kRgbUnorm8})
      for (int spp : kSpps) {
        const TraceHeader h = make_header(spp, d, c, Compression::kNone);
        const std::string path = tmp.path("spec.trace");
        const auto frags = make_fragments(h, 20, spp);
        std::vector<uint8_t> payload;
        {
          TraceWriter w(path, h);
          for (const auto& f : frags) {
            w.write(f);
            encode_fragment(payload, h, f);
          }
          w.finish();
        }
        encode_end(payload, frags.size());
        const std::vector<uint8_t> want = assemble(h, payload, frags.size());
        const std::vector<uint8_t> got = read_file(path);
        ASSERT_EQ(got.size(), want.size()) << to_string(d) << "/" << to_string(c) << "/" << spp << " spp: file size";
        size_t first_diff = 0;
        while (first_diff < got.size() && got[first_diff] == want[first_diff]) ++first_diff;
        EXPECT_EQ(first_diff, got.size()) << to_string(d) << "/" << to_string(c) << "/" << spp
                                          << " spp: first differing byte at offset " << first_diff;
      }
}

TEST(TraceFormat, FragmentRecordBytesMatchesThePayload) {
  TempDir tmp;
  for (DepthMode d : {DepthMode::kPlane, DepthMode::kPerSample})
    for (ColorFormat c : {ColorFormat::kRgbF32, ColorFormat::kRgbUnorm8})
      for (int spp : kSpps)
        for (int covered : {1, spp / 2 + 1, spp}) {
          if (covered > spp) continue;
          const TraceHeader h = make_header(spp, d, c, Compression::kNone);
          Fragment f = one_valid_fragment(h);
          f.coverage = spp_mask(covered);
          const std::string path = tmp.path("one.trace");
          {
            TraceWriter w(path, h);
            w.write(f);
            w.finish();
          }
          const size_t header_bytes = 48 + 2 * size_t(spp) + h.scene_name.size();
          const size_t record = fs::file_size(path) - header_bytes - 9;
          // The formula of docs/trace-format.md, independently.
          const size_t want = 1 + 4 + 4 + 2 + 2 + size_t((spp + 7) / 8) +
                              (d == DepthMode::kPlane ? 12 : 4 * size_t(covered)) +
                              (c == ColorFormat::kRgbF32 ? 12 : 3) + 4;
          EXPECT_EQ(fragment_record_bytes(h, covered), record)
              << to_string(d) << "/" << to_string(c) << " " << spp << " spp, " << covered << " covered";
          EXPECT_EQ(record, want) << to_string(d) << "/" << to_string(c) << " " << spp << " spp, " << covered
                                  << " covered";
          TraceReader r(path);
          Fragment g;
          ASSERT_TRUE(r.next(g));
          EXPECT_EQ(r.payload_bytes(), record) << "payload_bytes after one record";
        }
}

TEST(TraceFormat, TheHeaderRecordsTheFragmentCount) {
  // The writer records the count in bytes 42..47 (count + 1) once the
  // payload is written; a reader reports it before reading a record. Bytes
  // 42..47 of 0 (older writers, an output that cannot seek) record nothing.
  TempDir tmp;
  for (Compression z : {Compression::kNone, Compression::kZstd})
    for (size_t n : {size_t(0), size_t(1), size_t(3000)}) {
      SCOPED_TRACE(std::string(to_string(z)) + ", " + std::to_string(n) + " fragments");
      const TraceHeader h = make_header(4, DepthMode::kPerSample, ColorFormat::kRgbF32, z);
      const std::string path = tmp.path("counted.trace");
      {
        TraceWriter w(path, h);
        for (const auto& f : make_fragments(h, n, 4)) w.write(f);
        w.finish();
      }
      const std::vector<uint8_t> bytes = read_file(path);
      uint64_t field = 0;
      for (int i = 0; i < 6; ++i) field |= uint64_t(bytes[size_t(42 + i)]) << (8 * i);
      EXPECT_EQ(field, n + 1) << "bytes 42..47 hold the count + 1";
      TraceReader r(path);
      ASSERT_TRUE(r.recorded_fragments().has_value());
      EXPECT_EQ(*r.recorded_fragments(), n);
      Fragment f;
      size_t got = 0;
      while (r.next(f)) ++got;
      EXPECT_EQ(got, n);
    }
  const TraceHeader h = make_header(4, DepthMode::kPlane, ColorFormat::kRgbF32, Compression::kNone);
  std::vector<uint8_t> payload;
  encode_end(payload, 0);
  const std::string old = tmp.path("unrecorded.trace");
  write_file(old, assemble(h, payload));
  EXPECT_FALSE(TraceReader(old).recorded_fragments().has_value()) << "0 in bytes 42..47 records no count";
}

TEST(TraceFormat, AHeaderCountThatDisagreesWithTheRecordsIsRefused) {
  // Three fragments; the header claims two (the third record is refused,
  // naming it) or four (the end record is refused: per-sample records of
  // every sample, 46 bytes, leave room for four of the smallest, 34 bytes, so
  // the count passes the bound at open).
  TempDir tmp;
  const TraceHeader h = make_header(4, DepthMode::kPerSample, ColorFormat::kRgbF32, Compression::kNone);
  std::vector<uint8_t> payload;
  for (auto f : make_fragments(h, 3, 4)) {
    f.coverage = spp_mask(4);
    encode_fragment(payload, h, f);
  }
  encode_end(payload, 3);
  for (uint64_t claimed : {uint64_t(2), uint64_t(4)}) {
    const std::string path = tmp.path("claims-" + std::to_string(claimed) + ".trace");
    write_file(path, assemble(h, payload, claimed));
    TraceReader r(path);
    EXPECT_EQ(r.recorded_fragments(), std::optional<uint64_t>(claimed));
    Fragment f;
    try {
      while (r.next(f)) {
      }
      ADD_FAILURE() << "a header claiming " << claimed << " of 3 fragments was accepted";
    } catch (const TraceError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find(path), std::string::npos) << msg;
      EXPECT_EQ(msg.find('\n'), std::string::npos) << "one line: " << msg;
      if (claimed == 2) {
        EXPECT_NE(msg.find("record 2: a fragment record beyond the 2 the header records"), std::string::npos) << msg;
      } else {
        EXPECT_NE(msg.find("end record counts 3 fragments but the header records 4"), std::string::npos) << msg;
      }
    }
  }
}

TEST(TraceFormat, EmptyTraceIsValid) {
  TempDir tmp;
  for (Compression z : {Compression::kNone, Compression::kZstd}) {
    const TraceHeader h = make_header(4, DepthMode::kPlane, ColorFormat::kRgbF32, z);
    // Through the writer...
    const std::string a = tmp.path(std::string("empty-writer-") + to_string(z) + ".trace");
    {
      TraceWriter w(a, h);
      w.finish();
    }
    // ...and from the specification: header + end record (count 0).
    std::vector<uint8_t> payload;
    encode_end(payload, 0);
    const std::string b = tmp.path(std::string("empty-spec-") + to_string(z) + ".trace");
    write_file(b, assemble(h, payload));
    for (const std::string& p : {a, b}) {
      try {
        TraceReader r(p);
        Fragment f;
        EXPECT_FALSE(r.next(f)) << p << ": an empty trace has no fragments";
        EXPECT_EQ(r.records_read(), 0u) << p;
        EXPECT_EQ(r.header().scene_name, h.scene_name) << p;
      } catch (const TraceError& e) {
        ADD_FAILURE() << p << ": an empty trace (header + end record) is valid, but: " << e.what();
      }
    }
  }
  const std::string zero = tmp.path("zero-bytes.trace");
  write_file(zero, {});
  expect_trace_error(zero, -1, "header", "a zero-byte file is not a trace");
}

TEST(TraceFormat, MissingFileIsATraceError) {
  TempDir tmp;
  const std::string p = tmp.path("does-not-exist.trace");
  try {
    TraceReader r(p);
    ADD_FAILURE() << "opening a missing file did not throw";
  } catch (const TraceError& e) {
    const std::string m = e.what();
    EXPECT_EQ(m.rfind(p, 0), 0u) << "error does not name the file: " << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  }
}

TEST(TraceFormat, PlaneDepthAndCanonicalSampleDepths) {
  // docs/trace-format.md: sample i's depth is plane_depth(z0, dzdx, dzdy, ox, oy)
  // (rtl_models/algo/depth.h, the one definition) with ox = (pos.x - 128) / 256,
  // oy = (pos.y - 128) / 256, clamped to [0, 1]; stored per-sample -0 reads as +0.
  TraceHeader h = make_header(8, DepthMode::kPlane, ColorFormat::kRgbF32, Compression::kNone);
  h.positions[0] = {0, 0};
  h.positions[1] = {255, 128};
  h.positions[2] = {128, 255};
  h.positions[3] = {64, 192};
  h.positions[4] = {128, 128};  // the pixel centre: exactly z0
  Fragment f = one_valid_fragment(h);
  f.coverage = 0x1F;
  f.z0 = 0.3f;
  f.dzdx = 0.1f;
  f.dzdy = -0.7f;
  float z[64];
  fragment_sample_depths(h, f, z);
  for (int i = 0; i < 5; ++i) {
    const float ox = (float(h.positions[i].x) - 128.0f) / 256.0f, oy = (float(h.positions[i].y) - 128.0f) / 256.0f;
    const float want = plane_depth(f.z0, f.dzdx, f.dzdy, ox, oy);
    EXPECT_EQ(bits(z[i]), bits(want)) << "sample " << i << ": " << hexbits(z[i]) << " vs " << hexbits(want);
    const double exact = double(f.z0) + double(f.dzdx) * ox + double(f.dzdy) * oy;
    EXPECT_NEAR(z[i], std::min(1.0, std::max(0.0, exact)), 1e-7) << "sample " << i << " is not on the plane";
  }
  EXPECT_EQ(bits(z[4]), bits(f.z0)) << "at the pixel centre the depth must be z0 exactly";
  f.z0 = 2.0f;  // clamped to 1
  fragment_sample_depths(h, f, z);
  EXPECT_EQ(z[1], 1.0f) << "plane depth above 1 must clamp to 1";
  f.z0 = -2.0f;  // clamped to +0
  fragment_sample_depths(h, f, z);
  EXPECT_EQ(bits(z[1]), 0u) << "plane depth below 0 must clamp to +0, got " << hexbits(z[1]);

  TempDir tmp;
  TraceHeader hs = make_header(2, DepthMode::kPerSample, ColorFormat::kRgbF32, Compression::kZstd);
  Fragment g = one_valid_fragment(hs);
  g.z[0] = -0.0f;
  g.z[1] = 1.0f;
  const std::string path = tmp.path("neg-zero.trace");
  {
    TraceWriter w(path, hs);
    w.write(g);
    w.finish();
  }
  TraceReader r(path);
  Fragment back;
  ASSERT_TRUE(r.next(back)) << "a per-sample depth of -0 is valid";
  fragment_sample_depths(hs, back, z);
  EXPECT_EQ(bits(z[0]), 0u) << "-0 depth must be canonicalised to +0, got " << hexbits(z[0]);
  EXPECT_EQ(z[1], 1.0f);
}

TEST(TraceFormat, StandardSamplePositions) {
  // docs/trace-format.md: 1 spp at the centre; 2..16 the D3D/Vulkan patterns
  // (1/16-pixel grid); 32 and 64 a Hammersley net with one sample per column and row.
  auto p1 = standard_sample_positions(1);
  EXPECT_EQ(p1[0].x, 128);
  EXPECT_EQ(p1[0].y, 128);
  auto p4 = standard_sample_positions(4);
  const int want4[4][2] = {{96, 32}, {224, 96}, {32, 160}, {160, 224}};
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(p4[i].x, want4[i][0]) << "4 spp sample " << i;
    EXPECT_EQ(p4[i].y, want4[i][1]) << "4 spp sample " << i;
  }
  for (int spp : {2, 4, 8, 16}) {
    auto p = standard_sample_positions(spp);
    std::set<std::pair<int, int>> seen;
    for (int i = 0; i < spp; ++i) {
      EXPECT_EQ(p[i].x % 16, 0) << spp << " spp sample " << i << " is not on the 1/16 grid";
      EXPECT_EQ(p[i].y % 16, 0) << spp << " spp sample " << i << " is not on the 1/16 grid";
      EXPECT_TRUE(seen.insert({p[i].x, p[i].y}).second) << spp << " spp: duplicate position " << i;
    }
  }
  for (int spp : {32, 64}) {
    auto p = standard_sample_positions(spp);
    const int cell = 256 / spp;
    std::set<int> cols, rows;
    for (int i = 0; i < spp; ++i) {
      EXPECT_EQ(p[i].x, cell * i + cell / 2) << spp << " spp sample " << i;
      cols.insert(p[i].x / cell);
      rows.insert(p[i].y / cell);
    }
    EXPECT_EQ(int(cols.size()), spp) << spp << " spp: not one sample per column";
    EXPECT_EQ(int(rows.size()), spp) << spp << " spp: not one sample per row";
  }
}

// ------------------------------------------------------------------ streaming

void read_two_million(bool checksummed) {
  TempDir tmp;
  const std::string path = tmp.path("big.trace");
  TraceHeader h = make_header(4, DepthMode::kPlane, ColorFormat::kRgbF32, Compression::kZstd, 1024, 1024);
  h.checksummed = checksummed;
  constexpr uint64_t kN = 2'000'000;
  {
    TraceWriter w(path, h, 1);
    Fragment f = one_valid_fragment(h);
    uint32_t s = 12345;
    for (uint64_t i = 0; i < kN; ++i) {
      s = s * 1664525u + 1013904223u;
      f.prim_id = uint32_t(i);
      f.x = uint16_t(s >> 8 & 1023);
      f.y = uint16_t(s >> 20 & 1023);
      f.coverage = (s >> 3 & 15) | 1;
      f.z0 = float(s >> 9) * 0x1p-23f;
      f.alpha = float(i & 255) / 255.0f;
      w.write(f);
    }
    w.finish();
  }
  const size_t rss_before = current_rss_bytes();
  ASSERT_GT(rss_before, 0u) << "cannot read VmRSS from /proc/self/status";
  const auto t0 = std::chrono::steady_clock::now();
  uint64_t n = 0, sum = 0;
  size_t rss_after = 0;
  {
    TraceReader r(path);
    Fragment f;
    while (r.next(f)) {
      ++n;
      sum += f.prim_id;
    }
    rss_after = current_rss_bytes();
    EXPECT_EQ(r.payload_bytes(), kN * fragment_record_bytes(h, 1) + 9);
  }
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(n, kN) << "fragments read";
  EXPECT_EQ(sum, kN * (kN - 1) / 2) << "fragments read out of order or altered";
  const double grew_mib = (double(rss_after) - double(rss_before)) / (1024.0 * 1024.0);
  EXPECT_LT(grew_mib, 16.0) << "reading " << kN << " fragments grew VmRSS by " << grew_mib << " MiB (from "
                            << rss_before << " to " << rss_after << " bytes): the reader does not stream";
  EXPECT_LT(secs, 5.0) << "reading " << kN << " fragments took " << secs << " s";
  std::printf("[ info     ] read %llu fragments (%.1f MB file%s) in %.2f s; VmRSS grew %.2f MiB\n",
              static_cast<unsigned long long>(n), fs::file_size(path) / 1e6, checksummed ? ", checksummed" : "", secs,
              grew_mib);
}

TEST(TraceStreaming, TwoMillionFragmentsInConstantMemory) {
  for (bool checksummed : {false, true}) {
    SCOPED_TRACE(checksummed ? "checksummed" : "without checksum");
    read_two_million(checksummed);
  }
}

// ------------------------------------------------------------------ the writer refuses

struct BadFragment {
  const char* what;
  const char* needle;  ///< a word of the expected message
  DepthMode depth;
  ColorFormat colour;
  std::function<void(const TraceHeader&, Fragment&)> spoil;
};

std::vector<BadFragment> bad_fragments() {
  const DepthMode P = DepthMode::kPlane, S = DepthMode::kPerSample;
  const ColorFormat F = ColorFormat::kRgbF32, U = ColorFormat::kRgbUnorm8;
  return {
      {"pixel x outside the screen", "outside", P, F,
       [](const TraceHeader& h, Fragment& f) { f.x = uint16_t(h.width); }},
      {"pixel y outside the screen", "outside", S, U,
       [](const TraceHeader& h, Fragment& f) { f.y = uint16_t(h.height + 7); }},
      {"coverage bit beyond spp", "beyond", P, F,
       [](const TraceHeader& h, Fragment& f) { f.coverage |= uint64_t{1} << h.spp; }},
      {"coverage top bit beyond spp", "beyond", S, F, [](const TraceHeader&, Fragment& f) { f.coverage = 0x80; }},
      {"empty coverage", "empty coverage", P, U, [](const TraceHeader&, Fragment& f) { f.coverage = 0; }},
      {"NaN sample depth", "depth of sample 2", S, F, [](const TraceHeader&, Fragment& f) { f.z[2] = kNaN; }},
      {"+inf sample depth", "depth of sample 0", S, F, [](const TraceHeader&, Fragment& f) { f.z[0] = kInf; }},
      {"-inf sample depth", "depth of sample 3", S, U, [](const TraceHeader&, Fragment& f) { f.z[3] = -kInf; }},
      {"sample depth above 1", "depth of sample 1", S, F, [](const TraceHeader&, Fragment& f) { f.z[1] = 1.0000001f; }},
      {"negative sample depth", "depth of sample 0", S, F, [](const TraceHeader&, Fragment& f) { f.z[0] = -1e-30f; }},
      {"NaN plane z0", "plane", P, F, [](const TraceHeader&, Fragment& f) { f.z0 = kNaN; }},
      {"inf plane dzdx", "plane", P, U, [](const TraceHeader&, Fragment& f) { f.dzdx = kInf; }},
      {"NaN plane dzdy", "plane", P, F, [](const TraceHeader&, Fragment& f) { f.dzdy = -kNaN; }},
      {"NaN colour", "colour", P, F, [](const TraceHeader&, Fragment& f) { f.rgb[1] = kNaN; }},
      {"inf colour", "colour", S, F, [](const TraceHeader&, Fragment& f) { f.rgb[2] = kInf; }},
      {"negative colour", "colour", P, F, [](const TraceHeader&, Fragment& f) { f.rgb[0] = -0.25f; }},
      {"negative colour (unorm8)", "colour", P, U, [](const TraceHeader&, Fragment& f) { f.rgb[0] = -0.25f; }},
      {"NaN opacity", "opacity", P, F, [](const TraceHeader&, Fragment& f) { f.alpha = kNaN; }},
      {"negative opacity", "opacity", S, U, [](const TraceHeader&, Fragment& f) { f.alpha = -0.01f; }},
      {"opacity above 1", "opacity", P, U, [](const TraceHeader&, Fragment& f) { f.alpha = 1.01f; }},
      {"inf opacity", "opacity", S, F, [](const TraceHeader&, Fragment& f) { f.alpha = kInf; }},
  };
}

TEST(TraceWriterRefuses, InvalidFragmentsAndLeavesNoFile) {
  TempDir tmp;
  for (const BadFragment& bad : bad_fragments()) {
    SCOPED_TRACE(bad.what);
    const TraceHeader h = make_header(4, bad.depth, bad.colour, Compression::kZstd);
    const std::string path = tmp.path("refused.trace");
    {
      TraceWriter w(path, h);
      w.write(one_valid_fragment(h));
      w.write(one_valid_fragment(h));
      Fragment f = one_valid_fragment(h);
      bad.spoil(h, f);
      try {
        w.write(f);
        ADD_FAILURE() << "the writer accepted a fragment with " << bad.what;
      } catch (const TraceError& e) {
        const std::string m = e.what();
        EXPECT_EQ(m.rfind(path, 0), 0u) << "error does not name the file: " << m;
        EXPECT_NE(m.find(": record 2: "), std::string::npos) << "error does not name record 2: " << m;
        EXPECT_NE(m.find(bad.needle), std::string::npos) << "error lacks \"" << bad.needle << "\": " << m;
        EXPECT_EQ(m.find('\n'), std::string::npos) << m;
      }
      EXPECT_EQ(w.fragments(), 2u) << "a refused fragment must not be counted";
      // The writer writes to a unique temporary file .refused.trace.XXXXXX.
      int temps = 0;
      for (const auto& e : fs::directory_iterator(fs::path(path).parent_path()))
        temps += e.path().filename().string().rfind(".refused.trace.", 0) == 0;
      EXPECT_EQ(temps, 1) << "the writer should be writing to one temporary file .refused.trace.XXXXXX";
      EXPECT_FALSE(fs::exists(path)) << "the final name must not exist before finish()";
      // destroyed without finish()
    }
    EXPECT_FALSE(fs::exists(path)) << "a writer destroyed without finish() left " << path;
    for (const auto& e : fs::directory_iterator(fs::path(path).parent_path()))
      EXPECT_NE(e.path().filename().string()[0], '.') << "a writer destroyed without finish() left " << e.path();
  }
}

TEST(TraceWriterRefuses, InvalidHeaders) {
  TempDir tmp;
  const std::string path = tmp.path("hdr.trace");
  std::vector<std::pair<const char*, std::function<void(TraceHeader&)>>> cases = {
      {"spp 0", [](TraceHeader& h) { h.spp = 0; }},
      {"spp 3", [](TraceHeader& h) { h.spp = 3; }},
      {"spp 65", [](TraceHeader& h) { h.spp = 65; }},
      {"spp 128", [](TraceHeader& h) { h.spp = 128; }},
      {"width 0", [](TraceHeader& h) { h.width = 0; }},
      {"height 40000", [](TraceHeader& h) { h.height = 40000; }},
      {"NaN clear depth", [](TraceHeader& h) { h.clear_depth = kNaN; }},
      {"negative clear colour", [](TraceHeader& h) { h.clear_color[1] = -1.0f; }},
      {"long scene name", [](TraceHeader& h) { h.scene_name.assign(70000, 'x'); }},
      {"scene name not UTF-8", [](TraceHeader& h) { h.scene_name = "caf\xe9"; }},
  };
  for (auto& [what, spoil] : cases) {
    TraceHeader h = make_header(4, DepthMode::kPlane, ColorFormat::kRgbF32, Compression::kNone);
    spoil(h);
    try {
      TraceWriter w(path, h);
      ADD_FAILURE() << "the writer accepted a header with " << what;
    } catch (const TraceError& e) {
      const std::string m = e.what();
      EXPECT_EQ(m.rfind(path + ": header: ", 0), 0u) << what << ": " << m;
    }
    EXPECT_FALSE(fs::exists(path)) << what;
    EXPECT_FALSE(fs::exists(path + ".tmp")) << what;
  }
}

TEST(TraceWriterRefuses, DestroyedWithoutFinishLeavesNothing) {
  TempDir tmp;
  for (Compression z : {Compression::kNone, Compression::kZstd}) {
    const TraceHeader h = make_header(8, DepthMode::kPerSample, ColorFormat::kRgbF32, z);
    const std::string path = tmp.path("unfinished.trace");
    {
      TraceWriter w(path, h);
      for (const auto& f : make_fragments(h, 5000, 7)) w.write(f);
    }
    EXPECT_FALSE(fs::exists(path)) << to_string(z) << ": unfinished writer left " << path;
    EXPECT_FALSE(fs::exists(path + ".tmp")) << to_string(z) << ": unfinished writer left " << path << ".tmp";
    EXPECT_TRUE(fs::is_empty(tmp.dir())) << to_string(z) << ": unfinished writer left files in " << tmp.dir();
  }
}

// ------------------------------------------------------------------ the reader refuses

/// A valid uncompressed trace of `n` fragments built from the specification,
/// with the byte offset where each record starts (the last entry: the end record).
struct Built {
  TraceHeader h;
  std::vector<uint8_t> header, payload;
  std::vector<size_t> record_offsets;  ///< within payload
};

Built build_valid(int spp, DepthMode d, ColorFormat c, size_t n) {
  Built b;
  b.h = make_header(spp, d, c, Compression::kNone);
  b.header = encode_header(b.h);
  for (const auto& f : make_fragments(b.h, n, 99)) {
    b.record_offsets.push_back(b.payload.size());
    encode_fragment(b.payload, b.h, f);
  }
  b.record_offsets.push_back(b.payload.size());
  encode_end(b.payload, n);
  return b;
}

TEST(TraceReaderRefuses, TruncatedUncompressed) {
  TempDir tmp;
  const Built b = build_valid(4, DepthMode::kPerSample, ColorFormat::kRgbUnorm8, 10);
  std::vector<uint8_t> file = b.header;
  file.insert(file.end(), b.payload.begin(), b.payload.end());
  const size_t H = b.header.size();
  struct Cut {
    size_t at;
    long long record;
    const char* needle;
    const char* what;
  };
  const std::vector<Cut> cuts = {
      {3, -1, "header", "inside the magic"},
      {20, -1, "header", "inside the fixed header"},
      {47, -1, "header", "one byte short of the fixed header"},
      {49, -1, "sample positions", "inside the sample positions"},
      {H - 1, -1, "scene name", "inside the scene name"},
      {H, 0, "truncated", "right after the header (no records)"},
      {H + 1, 0, "truncated", "inside record 0's ids"},
      {H + b.record_offsets[4] + 14, 4, "truncated", "inside record 4's depths"},
      {H + b.record_offsets[7] - 2, 6, "truncated", "inside record 6's opacity"},
      {H + b.record_offsets[7], 7, "truncated", "between records 6 and 7"},
      {H + b.record_offsets[10], 10, "end record", "just before the end record"},
      {H + b.record_offsets[10] + 1, 10, "end record", "inside the end record"},
      {file.size() - 1, 10, "end record", "one byte short of the end"},
  };
  for (const Cut& c : cuts) {
    const std::string path = tmp.path("cut-" + std::to_string(c.at) + ".trace");
    write_file(path, std::vector<uint8_t>(file.begin(), file.begin() + long(c.at)));
    expect_trace_error(path, c.record, c.needle, std::string("cut ") + c.what + " at byte " + std::to_string(c.at));
  }
  // The uncut file is valid (the cuts above are what break it).
  const std::string whole = tmp.path("whole.trace");
  write_file(whole, file);
  TraceReader r(whole);
  Fragment f;
  while (r.next(f)) {
  }
  EXPECT_EQ(r.records_read(), 10u);
}

TEST(TraceReaderRefuses, TruncatedCompressed) {
  TempDir tmp;
  // A compressed trace written by the writer, cut at many byte offsets:
  // every cut is an error naming the file (and a record within the trace).
  const TraceHeader h = make_header(16, DepthMode::kPlane, ColorFormat::kRgbF32, Compression::kZstd);
  const std::string good = tmp.path("good.trace");
  const auto frags = make_fragments(h, 20000, 5);
  {
    TraceWriter w(good, h);
    for (const auto& f : frags) w.write(f);
    w.finish();
  }
  const std::vector<uint8_t> file = read_file(good);
  const size_t H = encode_header(h).size();
  std::vector<size_t> cuts = {5, 30, H - 1, H, H + 1, H + 4, H + 100, file.size() / 2};
  for (size_t k = 1; k <= 12; ++k) cuts.push_back(file.size() - k);  // incl. every byte of the checksum
  for (size_t at : cuts) {
    SCOPED_TRACE("compressed trace cut at byte " + std::to_string(at) + " of " + std::to_string(file.size()));
    const std::string path = tmp.path("zcut-" + std::to_string(at) + ".trace");
    write_file(path, std::vector<uint8_t>(file.begin(), file.begin() + long(at)));
    const std::string msg = read_all_error(path);
    if (msg.empty()) continue;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    EXPECT_EQ(msg.rfind(path, 0), 0u) << "error does not name the file: " << msg;
    if (at < H) {
      EXPECT_NE(msg.find("header"), std::string::npos) << msg;
    } else if (frags.size() > max_fragments_in_payload(h, (at - H) * kZstdMaxRatio)) {
      // Too few bytes left for the count the header records: refused at open.
      EXPECT_NE(msg.find(": header: fragment count (bytes 42..47) 20000 is more than"), std::string::npos) << msg;
    } else {
      const long long rec = record_in(msg);
      EXPECT_GE(rec, 0) << "error does not name a record: " << msg;
      EXPECT_LE(rec, (long long)frags.size()) << msg;
    }
  }

  // Payloads cut at known places, then compressed as complete frames: the
  // record is known exactly.
  const Built b = build_valid(8, DepthMode::kPerSample, ColorFormat::kRgbF32, 12);
  TraceHeader hz = b.h;
  hz.compression = Compression::kZstd;
  struct PCut {
    size_t at;
    long long record;
    const char* what;
  };
  for (const PCut& c : {PCut{0, 0, "empty payload"}, PCut{b.record_offsets[5] + 3, 5, "inside record 5"},
                        PCut{b.record_offsets[12], 12, "just before the end record"},
                        PCut{b.record_offsets[12] + 5, 12, "inside the end record"}}) {
    const std::string path = tmp.path("pcut-" + std::to_string(c.at) + ".trace");
    write_file(path, assemble(hz, std::vector<uint8_t>(b.payload.begin(), b.payload.begin() + long(c.at))));
    expect_trace_error(path, c.record, "truncated", std::string("compressed payload cut ") + c.what);
  }
}

TEST(TraceReaderRefuses, BadHeaders) {
  TempDir tmp;
  for (Compression z : {Compression::kNone, Compression::kZstd}) {
    const Built b = build_valid(4, DepthMode::kPlane, ColorFormat::kRgbF32, 3);
    TraceHeader h = b.h;
    h.compression = z;
    const std::vector<uint8_t> good = assemble(h, b.payload);
    struct Patch {
      const char* what;
      size_t offset;
      std::vector<uint8_t> bytes;
      const char* needle;
    };
    auto u32 = [](uint32_t v) {
      return std::vector<uint8_t>{uint8_t(v), uint8_t(v >> 8), uint8_t(v >> 16), uint8_t(v >> 24)};
    };
    auto f32 = [&](float f) { return u32(bits(f)); };
    const std::vector<Patch> patches = {
        {"wrong magic", 0, {'R', 'O', 'P', 'T', 'R', 'A', 'C', 'X'}, "magic"},
        {"lower-case magic", 0, {'r'}, "magic"},
        {"version 0", 8, {0, 0}, "version 0"},
        {"version 3", 8, {3, 0}, "unsupported version 3 (this reader reads 1 and 2)"},
        {"version 256", 8, {0, 1}, "version 256"},
        {"spp 0", 20, {0}, "samples per pixel 0"},
        {"spp 3", 20, {3}, "samples per pixel 3"},
        {"spp 65", 20, {65}, "samples per pixel 65"},
        {"spp 128", 20, {128}, "samples per pixel 128"},
        {"spp 255", 20, {255}, "samples per pixel 255"},
        {"width 0", 12, u32(0), "width"},
        {"width 40000", 12, u32(40000), "width"},
        {"height 0", 16, u32(0), "height"},
        {"height 40000", 16, u32(40000), "height"},
        {"depth mode 2", 21, {2}, "depth mode"},
        {"colour format 7", 22, {7}, "colour format"},
        {"compression 2", 23, {2}, "compression"},
        {"NaN clear colour", 28, f32(kNaN), "clear colour"},
        {"negative clear colour", 24, f32(-1.0f), "clear colour"},
        {"inf clear colour", 32, f32(kInf), "clear colour"},
        {"clear depth 1.5", 36, f32(1.5f), "clear depth"},
        {"NaN clear depth", 36, f32(kNaN), "clear depth"},
        {"scene name longer than the file", 40, {0xFF, 0xFF}, "scene name"},
    };
    for (const Patch& p : patches) {
      std::vector<uint8_t> bad = good;
      std::copy(p.bytes.begin(), p.bytes.end(), bad.begin() + long(p.offset));
      const std::string path = tmp.path(std::string("hdr-") + to_string(z) + ".trace");
      write_file(path, bad);
      expect_trace_error(path, -1, p.needle, std::string(to_string(z)) + ": " + p.what);
    }
    const std::string text = tmp.path("text.trace");
    write_file(text, {'h', 'e', 'l', 'l', 'o', '\n'});
    expect_trace_error(text, -1, "magic", "a short non-trace file");
  }
}

// A scene name that is not well-formed UTF-8 is refused with the header, in
// one line naming the file; well-formed names of every sequence length pass.
TEST(TraceReaderRefuses, SceneNameNotUtf8) {
  TempDir tmp;
  const Built b = build_valid(4, DepthMode::kPlane, ColorFormat::kRgbF32, 3);
  const std::vector<std::pair<const char*, std::string>> bad = {
      {"Latin-1 byte", "caf\xe9"},
      {"lone continuation byte", "a\x80z"},
      {"overlong NUL", std::string("\xc0\x80", 2)},
      {"overlong slash", "\xc1\xaf"},
      {"overlong 3-byte", "\xe0\x9f\xbf"},
      {"overlong 4-byte", "\xf0\x8f\xbf\xbf"},
      {"high surrogate", "\xed\xa0\x80"},
      {"low surrogate", "x\xed\xbf\xbf"},
      {"U+110000", "\xf4\x90\x80\x80"},
      {"lead F5", "\xf5\x80\x80\x80"},
      {"byte FF", "\xff"},
      {"truncated at the end", "euro \xe2\x82"},
      {"truncated before ASCII", "\xe2\x82x"},
  };
  for (Compression z : {Compression::kNone, Compression::kZstd}) {
    for (const auto& [what, name] : bad) {
      TraceHeader h = b.h;
      h.compression = z;
      h.scene_name = name;
      const std::string path = tmp.path("name.trace");
      write_file(path, assemble(h, b.payload));
      const std::string ctx = std::string(to_string(z)) + ": " + what;
      expect_trace_error(path, -1, "header: scene name is not valid UTF-8", ctx);
      EXPECT_EQ(read_all_error(path), path + ": header: scene name is not valid UTF-8") << ctx;
    }
    TraceHeader h = b.h;
    h.compression = z;
    static const char kGood[] = "nul \0 \xc2\xa9 \xe2\x82\xac \xef\xbf\xbf \xf0\x9f\x8e\xa8 \xf4\x8f\xbf\xbf";
    h.scene_name = std::string(kGood, sizeof kGood - 1);  // the NUL inside included
    const std::string path = tmp.path("good-name.trace");
    write_file(path, assemble(h, b.payload));
    TraceReader r(path);
    EXPECT_EQ(r.header().scene_name, h.scene_name);
  }
}

namespace {
std::string utf8_encode(uint32_t cp) {
  if (cp < 0x80) return std::string(1, char(cp));
  if (cp < 0x800) return {char(0xC0 | cp >> 6), char(0x80 | (cp & 0x3F))};
  if (cp < 0x10000) return {char(0xE0 | cp >> 12), char(0x80 | (cp >> 6 & 0x3F)), char(0x80 | (cp & 0x3F))};
  return {char(0xF0 | cp >> 18), char(0x80 | (cp >> 12 & 0x3F)), char(0x80 | (cp >> 6 & 0x3F)),
          char(0x80 | (cp & 0x3F))};
}
}  // namespace

// The validator against an oracle built from the encoder: a string is valid
// exactly when it splits into encodings of scalar values (U+0000..U+10FFFF
// without the surrogates). Every string of up to 3 bytes is checked, and
// every scalar value's 4-byte encoding and its neighbours.
TEST(Utf8, AcceptsExactlyTheEncodingsOfScalarValues) {
  std::unordered_set<std::string> enc;  // encodings of 1 to 3 bytes
  for (uint32_t cp = 0; cp < 0x10000; ++cp)
    if (cp < 0xD800 || cp > 0xDFFF) enc.insert(utf8_encode(cp));
  const auto oracle = [&](const std::string& s) {  // splits into encodings (s up to 3 bytes)
    std::vector<bool> ok(s.size() + 1, false);
    ok[0] = true;
    for (size_t i = 0; i < s.size(); ++i)
      for (size_t len = 1; ok[i] && len <= 3 && i + len <= s.size(); ++len)
        if (enc.count(s.substr(i, len))) ok[i + len] = true;
    return bool(ok[s.size()]);
  };
  EXPECT_TRUE(is_valid_utf8(""));
  for (uint32_t v = 0; v < (1u << 24); ++v) {
    std::string s = {char(v >> 16), char(v >> 8), char(v)};
    for (size_t n : {size_t(3), size_t(2), size_t(1)}) {
      if (n < 3 && (v >> (8 * n)) != 0) break;  // each shorter string once
      const std::string t = s.substr(3 - n);
      if (is_valid_utf8(t) != oracle(t)) {
        ADD_FAILURE() << "bytes " << std::hex << v << " (" << n << "): validator says " << is_valid_utf8(t);
        return;
      }
    }
  }
  for (uint32_t cp = 0; cp <= 0x10FFFF; ++cp) {
    const std::string e = utf8_encode(cp);
    const bool scalar = cp < 0xD800 || cp > 0xDFFF;
    if (is_valid_utf8(e) != scalar) {
      ADD_FAILURE() << "U+" << std::hex << cp;
      return;
    }
    if (e.size() == 4) {
      ASSERT_FALSE(is_valid_utf8(e.substr(0, 3))) << "truncated U+" << std::hex << cp;
      ASSERT_FALSE(is_valid_utf8(e.substr(1))) << "lead byte missing, U+" << std::hex << cp;
    }
  }
  // Above U+10FFFF, overlong 4-byte forms, the leads that are never valid.
  EXPECT_FALSE(is_valid_utf8("\xf4\x90\x80\x80"));
  EXPECT_FALSE(is_valid_utf8("\xf7\xbf\xbf\xbf"));
  EXPECT_FALSE(is_valid_utf8("\xf0\x80\x80\x80"));
  EXPECT_FALSE(is_valid_utf8("\xf0\x8f\xbf\xbf"));
  EXPECT_TRUE(is_valid_utf8("\xf0\x90\x80\x80"));
  EXPECT_TRUE(is_valid_utf8("\xf4\x8f\xbf\xbf"));
  for (int lead = 0xF5; lead <= 0xFF; ++lead)
    EXPECT_FALSE(is_valid_utf8(std::string{char(lead), '\x80', '\x80', '\x80'})) << std::hex << lead;
}

TEST(TraceReaderRefuses, BadFragmentRecords) {
  TempDir tmp;
  for (const BadFragment& bad : bad_fragments()) {
    for (Compression z : {Compression::kNone, Compression::kZstd}) {
      TraceHeader h = make_header(4, bad.depth, bad.colour, z);
      Fragment f = one_valid_fragment(h);
      bad.spoil(h, f);
      if (bad.colour == ColorFormat::kRgbUnorm8 && std::string(bad.needle) == "colour")
        continue;  // 8-bit colour cannot encode a bad value: the writer's refusal is the test
      std::vector<uint8_t> payload;
      for (int i = 0; i < 3; ++i) encode_fragment(payload, h, one_valid_fragment(h));
      encode_fragment(payload, h, f);
      encode_fragment(payload, h, one_valid_fragment(h));
      encode_end(payload, 5);
      const std::string path = tmp.path(std::string("bad-") + to_string(z) + ".trace");
      write_file(path, assemble(h, payload));
      expect_trace_error(path, 3, bad.needle, std::string(to_string(z)) + ": " + bad.what);
    }
  }
}

TEST(TraceReaderRefuses, BadRecordStructure) {
  TempDir tmp;
  for (Compression z : {Compression::kNone, Compression::kZstd}) {
    const Built b = build_valid(2, DepthMode::kPlane, ColorFormat::kRgbUnorm8, 6);
    TraceHeader h = b.h;
    h.compression = z;
    const std::vector<uint8_t> records(b.payload.begin(), b.payload.begin() + long(b.record_offsets[6]));
    auto check = [&](const char* what, const std::vector<uint8_t>& payload, long long rec, const char* needle) {
      const std::string path = tmp.path(std::string("struct-") + to_string(z) + ".trace");
      write_file(path, assemble(h, payload));
      expect_trace_error(path, rec, needle, std::string(to_string(z)) + ": " + what);
    };
    {
      auto p = records;
      encode_end(p, 7);
      check("end record counts 7 of 6", p, 6, "end record counts 7");
    }
    {
      auto p = records;
      encode_end(p, 5);
      check("end record counts 5 of 6", p, 6, "end record counts 5");
    }
    {
      auto p = records;
      encode_end(p, 6);
      p.push_back(0);
      check("a byte after the end record", p, 6, "after the end record");
    }
    {
      auto p = records;
      encode_end(p, 6);
      encode_end(p, 6);
      check("a second end record", p, 6, "after the end record");
    }
    for (uint8_t tag : {uint8_t(0x00), uint8_t(0x02), uint8_t(0xFE)}) {
      auto p = std::vector<uint8_t>(b.payload.begin(), b.payload.begin() + long(b.record_offsets[4]));
      p.push_back(tag);
      p.insert(p.end(), b.payload.begin() + long(b.record_offsets[4]) + 1, b.payload.end());
      // Tag 2 is the checksum record: refused in a trace whose header does not flag checksums.
      const std::string needle = tag == kTagChecksum ? "checksum record (tag 2) in a trace whose header does not flag"
                                                     : "unknown record tag " + std::to_string(tag);
      check("unknown record tag", p, 4, needle.c_str());
    }
    {
      std::vector<uint8_t> p;
      check("no end record at all (empty payload)", p, 0, "truncated");
    }
  }
}

TEST(TraceReaderRefuses, DataAfterTheCompressedFrame) {
  TempDir tmp;
  const Built b = build_valid(4, DepthMode::kPlane, ColorFormat::kRgbF32, 5);
  TraceHeader h = b.h;
  h.compression = Compression::kZstd;
  std::vector<uint8_t> file = assemble(h, b.payload);
  const std::string ok = tmp.path("ok.trace");
  write_file(ok, file);
  {
    TraceReader r(ok);
    Fragment f;
    while (r.next(f)) {
    }
    EXPECT_EQ(r.records_read(), 5u);
  }
  for (const std::vector<uint8_t>& tail : {std::vector<uint8_t>{0}, std::vector<uint8_t>{'j', 'u', 'n', 'k'},
                                           zstd_compress(std::vector<uint8_t>{1, 2, 3})}) {
    std::vector<uint8_t> bad = file;
    bad.insert(bad.end(), tail.begin(), tail.end());
    const std::string path = tmp.path("tail.trace");
    write_file(path, bad);
    expect_trace_error(path, 5, "after the end", std::to_string(tail.size()) + " bytes after the zstd frame");
  }
}

TEST(TraceReaderRefuses, CorruptCompressedData) {
  TempDir tmp;
  const TraceHeader h = make_header(8, DepthMode::kPlane, ColorFormat::kRgbF32, Compression::kZstd);
  const std::string good = tmp.path("good.trace");
  {
    TraceWriter w(good, h);
    for (const auto& f : make_fragments(h, 5000, 11)) w.write(f);
    w.finish();
  }
  const std::vector<uint8_t> file = read_file(good);
  const size_t H = encode_header(h).size();
  int corrupted = 0;
  for (size_t at : {H, H + 1, H + 2, H + 3, H + 40, H + (file.size() - H) / 2, file.size() - 40, file.size() - 2}) {
    std::vector<uint8_t> bad = file;
    bad[at] ^= 0xA5;
    const std::string path = tmp.path("corrupt-" + std::to_string(at) + ".trace");
    write_file(path, bad);
    SCOPED_TRACE("byte " + std::to_string(at) + " of " + std::to_string(file.size()) + " flipped");
    const std::string msg = read_all_error(path);
    if (msg.empty()) continue;
    ++corrupted;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    EXPECT_EQ(msg.rfind(path, 0), 0u) << "error does not name the file: " << msg;
    EXPECT_GE(record_in(msg), 0) << "error does not name a record: " << msg;
  }
  EXPECT_EQ(corrupted, 8);
}

// ------------------------------------------------------------------ checksummed payloads (section 2.3)

/// Header for a checksummed trace (make_header writes the unflagged layout).
TraceHeader make_ck_header(int spp, DepthMode d, ColorFormat c, Compression z) {
  TraceHeader h = make_header(spp, d, c, z);
  h.checksummed = true;
  return h;
}

/// A checksummed payload built from the specification: the fragment records in
/// blocks of at most 65536 bytes (a block is closed when the next record would
/// not fit), each block preceded by a checksum record (tag 2, u32 length, u64
/// XXH3-64 of the block, seed 0), then the end record.
struct CkBuilt {
  TraceHeader h;
  std::vector<uint8_t> header, payload;
  std::vector<size_t> block_offsets;   ///< payload offset of each block's checksum record
  std::vector<uint64_t> block_first;   ///< number of each block's first record
  std::vector<size_t> record_offsets;  ///< payload offset of each fragment record; last: the end record
};

CkBuilt build_checksummed(const TraceHeader& h, const std::vector<Fragment>& frags) {
  CkBuilt b;
  b.h = h;
  b.h.checksummed = true;
  b.header = encode_header(b.h);
  std::vector<std::vector<uint8_t>> recs;
  for (const Fragment& f : frags) {
    recs.emplace_back();
    encode_fragment(recs.back(), b.h, f);
  }
  for (size_t i = 0; i < recs.size();) {
    size_t j = i, len = 0;
    while (j < recs.size() && len + recs[j].size() <= 65536) len += recs[j++].size();
    std::vector<uint8_t> block;
    for (size_t k = i; k < j; ++k) block.insert(block.end(), recs[k].begin(), recs[k].end());
    b.block_offsets.push_back(b.payload.size());
    b.block_first.push_back(i);
    put8(b.payload, 0x02);
    put32(b.payload, uint32_t(block.size()));
    put64(b.payload, XXH3_64bits(block.data(), block.size()));
    for (size_t k = i; k < j; ++k) {
      b.record_offsets.push_back(b.payload.size());
      b.payload.insert(b.payload.end(), recs[k].begin(), recs[k].end());
    }
    i = j;
  }
  b.record_offsets.push_back(b.payload.size());
  encode_end(b.payload, recs.size());
  return b;
}

std::vector<uint8_t> zstd_decompress(const uint8_t* data, size_t size) {
  std::vector<uint8_t> out, buf(ZSTD_DStreamOutSize());
  ZSTD_DCtx* d = ZSTD_createDCtx();
  ZSTD_inBuffer in{data, size, 0};
  size_t r = 1;
  while (r != 0 && !ZSTD_isError(r)) {
    ZSTD_outBuffer o{buf.data(), buf.size(), 0};
    r = ZSTD_decompressStream(d, &o, &in);
    out.insert(out.end(), buf.begin(), buf.begin() + long(o.pos));
    if (in.pos == in.size && o.pos == 0 && r != 0) break;
  }
  EXPECT_FALSE(ZSTD_isError(r)) << ZSTD_getErrorName(r);
  ZSTD_freeDCtx(d);
  return out;
}

/// "block K (records from A, payload byte O)", as the reader names a block.
std::string block_name(const CkBuilt& b, size_t k) {
  return "block " + std::to_string(k) + " (records from " + std::to_string(b.block_first[k]) + ", payload byte " +
         std::to_string(b.block_offsets[k]) + ")";
}

/// Reads a trace until it throws; returns the message ("" and a failure when it
/// does not throw) and the number of fragments next() handed out before.
std::string read_until_error(const std::string& path, uint64_t& handed_out) {
  handed_out = 0;
  try {
    TraceReader r(path);
    Fragment f;
    while (r.next(f)) ++handed_out;
    ADD_FAILURE() << path << ": expected a TraceError, but the whole trace was read";
  } catch (const TraceError& e) {
    return e.what();
  }
  return "";
}

void expect_one_line_from(const std::string& msg, const std::string& path) {
  EXPECT_EQ(msg.find('\n'), std::string::npos) << "error is not one line: " << msg;
  EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << "error does not start with the file " << path << ": " << msg;
}

TEST(ChecksumFormat, WriterBytesMatchTheSpecification) {
  // Uncompressed: the whole file byte for byte. zstd: the header byte for byte
  // and the decompressed payload (the blocks live inside the decompressed stream).
  TempDir tmp;
  for (Compression z : {Compression::kNone, Compression::kZstd})
    for (DepthMode d : {DepthMode::kPlane, DepthMode::kPerSample})
      for (ColorFormat c : {ColorFormat::kRgbF32, ColorFormat::kRgbUnorm8})
        for (int spp : kSpps) {
          SCOPED_TRACE(std::string(to_string(z)) + "/" + to_string(d) + "/" + to_string(c) + "/" + std::to_string(spp) +
                       " spp");
          const TraceHeader h = make_ck_header(spp, d, c, z);
          const auto frags = make_fragments(h, 4000, 700 + spp);
          const std::string path = tmp.path("ck.trace");
          uint64_t writer_blocks = 0;
          {
            TraceWriter w(path, h);
            for (const auto& f : frags) w.write(f);
            w.finish();
            writer_blocks = w.blocks();
          }
          const CkBuilt b = build_checksummed(h, frags);
          ASSERT_GE(b.block_offsets.size(), 2u) << "the test data should span several blocks";
          EXPECT_EQ(writer_blocks, b.block_offsets.size());
          const std::vector<uint8_t> got = read_file(path);
          ASSERT_GE(got.size(), b.header.size());
          EXPECT_EQ(got[10], 3) << "header flags (offset 10) must be 3: the payload is checksummed, the header checked";
          EXPECT_EQ(got[11], 0);
          const std::vector<uint8_t> header = encode_header(h, frags.size());
          EXPECT_EQ(ropsim_test::first_element_difference(
                        header, std::vector<uint8_t>(got.begin(), got.begin() + long(header.size()))),
                    "")
              << "header bytes differ";
          const std::vector<uint8_t> payload =
              z == Compression::kNone ? std::vector<uint8_t>(got.begin() + long(b.header.size()), got.end())
                                      : zstd_decompress(got.data() + b.header.size(), got.size() - b.header.size());
          ASSERT_EQ(payload.size(), b.payload.size()) << "payload size";
          size_t first_diff = 0;
          while (first_diff < payload.size() && payload[first_diff] == b.payload[first_diff]) ++first_diff;
          EXPECT_EQ(first_diff, payload.size()) << "first differing payload byte at offset " << first_diff;
          TraceReader r(path);
          Fragment f;
          uint64_t n = 0;
          while (r.next(f)) ++n;
          EXPECT_EQ(n, frags.size());
          EXPECT_EQ(r.blocks_read(), b.block_offsets.size());
          EXPECT_EQ(r.payload_bytes(), b.payload.size() - 13 * b.block_offsets.size())
              << "payload_bytes counts fragment and end records, not checksum records";
        }
}

TEST(ChecksumFormat, ABlockHoldsAtMost65536BytesOfWholeRecords) {
  // Per-sample depth, rgb-unorm8, 32 spp, 2 covered samples: 32-byte records,
  // so 2048 of them fill a block exactly and the 2049th opens a second block.
  TempDir tmp;
  const TraceHeader h = make_ck_header(32, DepthMode::kPerSample, ColorFormat::kRgbUnorm8, Compression::kNone);
  ASSERT_EQ(fragment_record_bytes(h, 2), 32u);
  for (size_t n : {size_t(2047), size_t(2048), size_t(2049)}) {
    SCOPED_TRACE(std::to_string(n) + " fragments");
    Fragment f = one_valid_fragment(h);
    f.coverage = 0x3;
    const std::string path = tmp.path("edge.trace");
    {
      TraceWriter w(path, h);
      for (size_t i = 0; i < n; ++i) {
        f.prim_id = uint32_t(i);
        w.write(f);
      }
      w.finish();
    }
    const std::vector<uint8_t> file = read_file(path);
    const size_t H = encode_header(h).size();
    ASSERT_GT(file.size(), H + 13);
    EXPECT_EQ(file[H], kTagChecksum);
    const uint32_t len0 =
        uint32_t(file[H + 1]) | uint32_t(file[H + 2]) << 8 | uint32_t(file[H + 3]) << 16 | uint32_t(file[H + 4]) << 24;
    EXPECT_EQ(len0, 32 * std::min<size_t>(n, 2048)) << "first block length";
    const size_t after = H + 13 + len0;
    ASSERT_LT(after, file.size());
    EXPECT_EQ(file[after], n > 2048 ? kTagChecksum : kTagEnd) << "what follows the first block";
    if (n > 2048) {
      EXPECT_EQ(file[after + 1], 32) << "the second block holds the one remaining record";
    }
    EXPECT_EQ(file.size(), H + 13 * (n > 2048 ? 2 : 1) + 32 * n + 9) << "file size";
  }
}

// Records encoded apart (encode_fragment_record(), as the GL capture's
// threads do) and appended in runs of any size write the trace that
// write() of each fragment writes, byte for byte, blocks included; a run
// that does not frame, or a wrong count, is refused.
TEST(ChecksumFormat, EncodedRecordsWriteTheSameTraceAsFragments) {
  TempDir tmp;
  std::mt19937 rng(7);
  for (const bool checksummed : {true, false})
    for (const DepthMode d : {DepthMode::kPerSample, DepthMode::kPlane}) {
      SCOPED_TRACE(std::string(checksummed ? "checksummed " : "") + to_string(d));
      TraceHeader h = make_ck_header(16, d, ColorFormat::kRgbF32, Compression::kNone);
      h.checksummed = checksummed;
      std::vector<Fragment> frags;
      std::vector<uint8_t> records;
      for (uint32_t i = 0; i < 5000; ++i) {
        Fragment f = one_valid_fragment(h);
        f.prim_id = i;
        f.coverage = (rng() & 0xFFFF) | 1;
        f.z.fill(float(i % 100) / 100.0f);
        frags.push_back(f);
        uint8_t b[kMaxFragmentRecordBytes];
        std::string err;
        const size_t n = encode_fragment_record(h, f, b, err);
        ASSERT_EQ(err, "");
        ASSERT_EQ(n, fragment_record_bytes(h, __builtin_popcountll(f.coverage)));
        records.insert(records.end(), b, b + n);
      }
      const std::string a = tmp.path("a.trace"), b = tmp.path("b.trace");
      {
        TraceWriter w(a, h);
        for (const Fragment& f : frags) w.write(f);
        w.finish();
      }
      {
        TraceWriter w(b, h);
        // Runs of 1, 1000 and the rest of the records.
        size_t at = 0, done = 0;
        for (size_t run : {size_t(1), size_t(1000), frags.size() - 1001}) {
          size_t bytes = 0;
          for (size_t k = done; k < done + run; ++k)
            bytes += fragment_record_bytes(h, __builtin_popcountll(frags[k].coverage));
          w.write_records(records.data() + at, bytes, run);
          at += bytes;
          done += run;
        }
        w.finish();
      }
      EXPECT_EQ(read_file(a), read_file(b));
      TraceWriter w(tmp.path("c.trace"), h);
      const size_t first = fragment_record_bytes(h, __builtin_popcountll(frags[0].coverage));
      EXPECT_THROW(w.write_records(records.data(), first - 1, 1), TraceError);  // a record cut short
      EXPECT_THROW(w.write_records(records.data(), first, 2), TraceError);      // one record counted as two
      std::vector<uint8_t> bad(records.begin(), records.begin() + std::ptrdiff_t(first));
      bad[0] = kTagEnd;
      EXPECT_THROW(w.write_records(bad.data(), bad.size(), 1), TraceError);  // not a fragment record
    }
}

// A header-last writer (the records first, the header -- its draw table,
// clear values and scene name -- at finish()) writes the file a writer given
// that header first writes from the same records, byte for byte, with and
// without checksums and compression (zstd on 0 and 2 threads of its own),
// and with no records at all; finish(header) with another layout is refused.
TEST(ChecksumFormat, HeaderLastWritesTheSameTrace) {
  TempDir tmp;
  std::mt19937 rng(11);
  for (const bool checksummed : {true, false})
    for (const Compression z : {Compression::kNone, Compression::kZstd})
      for (const int workers : {0, 2})
        for (const size_t count : {size_t(0), size_t(6000)}) {
          SCOPED_TRACE(std::string(checksummed ? "checksummed " : "") + to_string(z) + " workers " +
                       std::to_string(workers) + " fragments " + std::to_string(count));
          TraceHeader layout = make_ck_header(16, DepthMode::kPerSample, ColorFormat::kRgbF32, z);
          layout.checksummed = checksummed;
          std::vector<uint8_t> records;
          size_t first_half = 0;  // bytes of the first count / 2 records
          for (uint32_t i = 0; i < count; ++i) {
            if (i == count / 2) first_half = records.size();
            Fragment f = one_valid_fragment(layout);
            f.draw_id = i % 2;
            f.prim_id = i;
            f.coverage = (rng() & 0xFFFF) | 1;
            f.z.fill(float(i % 100) / 100.0f);
            uint8_t b[kMaxFragmentRecordBytes];
            std::string err;
            const size_t n = encode_fragment_record(layout, f, b, err);
            ASSERT_EQ(err, "");
            records.insert(records.end(), b, b + n);
          }
          TraceHeader full = layout;
          full.draws = DrawTable({default_draw_state(0), default_draw_state(1)});
          full.clear_color = {0.25f, 0.5f, 0.75f};
          full.clear_depth = 0.5f;
          full.scene_name = "header last";
          const std::string a = tmp.path("a.trace"), b = tmp.path("b.trace");
          {
            TraceWriter w(a, full, 1, workers);
            w.write_records(records.data(), records.size(), count);
            w.finish();
          }
          {
            TraceWriter w(b, layout, 1, workers, TraceWriter::HeaderLast{});
            // In two runs, as the GL capture hands them over.
            w.write_records(records.data(), first_half, count / 2);
            w.write_records(records.data() + first_half, records.size() - first_half, count - count / 2);
            w.finish(full);
          }
          EXPECT_EQ(read_file(a), read_file(b));
          TraceReader r(b);
          EXPECT_EQ(r.header().scene_name, "header last");
          EXPECT_EQ(r.header().draws.size(), 2u);
          TraceWriter other(tmp.path("c.trace"), layout, 1, workers, TraceWriter::HeaderLast{});
          TraceHeader wider = full;
          wider.width += 1;
          EXPECT_THROW(other.finish(wider), TraceError);
          TraceWriter last(tmp.path("d.trace"), layout, 1, workers, TraceWriter::HeaderLast{});
          EXPECT_THROW(last.finish(), TraceError);  // a header-last writer needs its header
        }
}

TEST(ChecksumFormat, EmptyTraceHasNoBlock) {
  TempDir tmp;
  for (Compression z : {Compression::kNone, Compression::kZstd}) {
    const TraceHeader h = make_ck_header(4, DepthMode::kPlane, ColorFormat::kRgbF32, z);
    const std::string path = tmp.path("empty.trace");
    {
      TraceWriter w(path, h);
      w.finish();
      EXPECT_EQ(w.blocks(), 0u);
    }
    const CkBuilt b = build_checksummed(h, {});
    EXPECT_EQ(b.payload.size(), 9u) << "header + end record only";
    const std::vector<uint8_t> got = read_file(path);
    if (z == Compression::kNone) {
      EXPECT_EQ(got, assemble(b.h, b.payload, 0)) << "header (recording 0 fragments) + end record";
    }
    TraceReader r(path);
    EXPECT_TRUE(r.header().checksummed);
    Fragment f;
    EXPECT_FALSE(r.next(f));
    EXPECT_EQ(r.blocks_read(), 0u);
  }
}

TEST(ChecksumFlips, EveryRegionNamesTheBlockBothEncodings) {
  // A byte flipped in each region of a checksummed payload: a checksum record's
  // tag, length and hash, records at the start, middle and end of blocks, the
  // end record's tag and count. Uncompressed, and zstd (the flip is made in the
  // decompressed stream, and the frame has no zstd checksum, so the trace's own
  // checksum must catch it). No fragment of a damaged block is handed out.
  TempDir tmp;
  const TraceHeader h16 = make_ck_header(16, DepthMode::kPlane, ColorFormat::kRgbF32, Compression::kNone);
  const auto frags = make_fragments(h16, 5000, 31);
  for (Compression z : {Compression::kNone, Compression::kZstd}) {
    TraceHeader h = h16;
    h.compression = z;
    const CkBuilt b = build_checksummed(h, frags);
    const size_t nb = b.block_offsets.size();
    ASSERT_GE(nb, 3u);
    const size_t end = b.record_offsets.back();
    const size_t mid1 = b.record_offsets[b.block_first[1] + (b.block_first[2] - b.block_first[1]) / 2];
    struct Region {
      const char* what;
      size_t at;   ///< payload offset of the flipped byte
      long block;  ///< the block named; -1: the end record
      const char* needle;
    };
    const std::vector<Region> regions = {
        {"block 0 checksum tag", b.block_offsets[0], 0, "expected a checksum record"},
        {"block 0 length, low byte", b.block_offsets[0] + 1, 0, ""},
        {"block 1 length, high byte", b.block_offsets[1] + 4, 1, "exceeds the limit"},
        {"block 2 hash", b.block_offsets[2] + 8, 2, "checksum mismatch"},
        {"block 0 first record tag", b.record_offsets[0], 0, "checksum mismatch"},
        {"block 1 middle record, opacity", mid1 + 42, 1, "checksum mismatch"},
        {"block 1 middle record, x", mid1 + 9, 1, "checksum mismatch"},
        {"last byte of the last block", end - 1, long(nb - 1), "checksum mismatch"},
        {"end record tag", end, long(nb), "expected a checksum record (tag 2) or the end record"},
        {"end record count", end + 1, -1, "end record counts"},
        {"end record count, top byte", end + 8, -1, "end record counts"},
    };
    for (const Region& g : regions)
      for (uint8_t mask : {uint8_t(0x01), uint8_t(0x80)}) {
        SCOPED_TRACE(std::string(to_string(z)) + ": " + g.what + ", xor " + std::to_string(mask));
        std::vector<uint8_t> p = b.payload;
        p[g.at] ^= mask;
        const std::string path = tmp.path("flip.trace");
        write_file(path, assemble(b.h, p));
        uint64_t handed = 0;
        const std::string msg = read_until_error(path, handed);
        if (msg.empty()) continue;
        expect_one_line_from(msg, path);
        EXPECT_NE(msg.find(g.needle), std::string::npos) << "error lacks \"" << g.needle << "\": " << msg;
        if (g.block >= 0) {
          const std::string want = g.block < long(nb) ? block_name(b, size_t(g.block))
                                                      : "block " + std::to_string(nb) + " (records from " +
                                                            std::to_string(frags.size()) + ", payload byte " +
                                                            std::to_string(end) + ")";
          EXPECT_EQ(msg.rfind(path + ": " + want + ": ", 0), 0u) << "error does not name " << want << ": " << msg;
          const uint64_t first = g.block < long(nb) ? b.block_first[size_t(g.block)] : frags.size();
          EXPECT_EQ(handed, first) << "fragments of a damaged block were handed out before it was verified";
        } else {
          const std::string want =
              "end record at payload byte " + std::to_string(end) + " (after " + std::to_string(nb) + " blocks)";
          EXPECT_EQ(msg.rfind(path + ": " + want + ": ", 0), 0u) << "error does not name " << want << ": " << msg;
        }
      }
  }
}

TEST(ChecksumFlips, SweepOfTheWritersFilesBothEncodings) {
  // Every 499th byte after the header of a checksummed trace written by
  // TraceWriter, flipped: each is refused in one line naming a block (or the end
  // record). For zstd files the flip is in the compressed frame (zstd's own
  // frame checksum or data checks may find it first; the block is still named).
  TempDir tmp;
  const std::regex names_block(
      ": (block [0-9]+ \\(records from [0-9]+, payload byte [0-9]+\\)|end record at payload byte [0-9]+ "
      "\\(after [0-9]+ blocks\\)): ");
  for (Compression z : {Compression::kNone, Compression::kZstd}) {
    const TraceHeader h = make_ck_header(8, DepthMode::kPerSample, ColorFormat::kRgbF32, z);
    const std::string good = tmp.path("good.trace");
    {
      TraceWriter w(good, h);
      for (const auto& f : make_fragments(h, 4000, 5)) w.write(f);
      w.finish();
    }
    const std::vector<uint8_t> file = read_file(good);
    const size_t H = encode_header(h).size();
    int tried = 0;
    for (size_t at = H; at < file.size(); at += (z == Compression::kNone ? 499 : 97)) {
      std::vector<uint8_t> bad = file;
      bad[at] ^= 0x10;
      const std::string path = tmp.path("sweep.trace");
      write_file(path, bad);
      SCOPED_TRACE(std::string(to_string(z)) + ": byte " + std::to_string(at) + " of " + std::to_string(file.size()));
      uint64_t handed = 0;
      const std::string msg = read_until_error(path, handed);
      if (msg.empty()) continue;
      ++tried;
      expect_one_line_from(msg, path);
      EXPECT_TRUE(std::regex_search(msg, names_block)) << "error does not name a block: " << msg;
    }
    EXPECT_GE(tried, 20) << "too few positions tried";
  }
}

TEST(ChecksumReaderRefuses, TruncatedBlocksAndBadLengths) {
  TempDir tmp;
  const TraceHeader h0 = make_ck_header(4, DepthMode::kPerSample, ColorFormat::kRgbUnorm8, Compression::kNone);
  const auto frags = make_fragments(h0, 9000, 77);
  for (Compression z : {Compression::kNone, Compression::kZstd}) {
    TraceHeader hz = h0;
    hz.compression = z;
    const CkBuilt b = build_checksummed(hz, frags);
    ASSERT_GE(b.block_offsets.size(), 4u);
    const size_t nb = b.block_offsets.size(), end = b.record_offsets.back();
    auto set_len = [](std::vector<uint8_t>& p, size_t block_at, uint32_t len) {
      for (int i = 0; i < 4; ++i) p[block_at + 1 + size_t(i)] = uint8_t(len >> (8 * i));
    };
    auto get_len = [&](size_t k) {
      const size_t a = b.block_offsets[k] + 1;
      return uint32_t(b.payload[a]) | uint32_t(b.payload[a + 1]) << 8 | uint32_t(b.payload[a + 2]) << 16 |
             uint32_t(b.payload[a + 3]) << 24;
    };
    auto rehash = [](std::vector<uint8_t>& p, size_t block_at, uint32_t len) {
      const uint64_t x = XXH3_64bits(p.data() + block_at + 13, len);
      for (int i = 0; i < 8; ++i) p[block_at + 5 + size_t(i)] = uint8_t(x >> (8 * i));
    };
    struct Case {
      const char* what;
      std::vector<uint8_t> payload;
      std::string names;  ///< the start of the message after "PATH: "
      std::string needle;
      TraceHeader h;
    };
    std::vector<Case> cases;
    auto add = [&](const char* what, std::vector<uint8_t> p, std::string names, std::string needle,
                   const TraceHeader* h = nullptr) {
      cases.push_back({what, std::move(p), std::move(names), std::move(needle), h ? *h : b.h});
    };
    add("cut in the middle of block 1",
        std::vector<uint8_t>(b.payload.begin(), b.payload.begin() + long(b.block_offsets[1] + 13 + 100)),
        block_name(b, 1), "runs past the end of the payload (100 bytes follow the checksum record)");
    add("cut inside the checksum record of block 2",
        std::vector<uint8_t>(b.payload.begin(), b.payload.begin() + long(b.block_offsets[2] + 5)), block_name(b, 2),
        "truncated in the checksum record (5 of 13 bytes)");
    add("cut just before the end record", std::vector<uint8_t>(b.payload.begin(), b.payload.begin() + long(end)),
        "block " + std::to_string(nb), "ends without an end record");
    {
      auto p = b.payload;
      set_len(p, b.block_offsets[1], 0);
      add("block length 0", p, block_name(b, 1), "block length 0");
    }
    {
      auto p = b.payload;
      set_len(p, b.block_offsets[1], (1u << 20) + 1);
      add("block length above 1 MiB", p, block_name(b, 1), "block length 1048577 exceeds the limit of 1048576");
    }
    {
      auto p = b.payload;
      set_len(p, b.block_offsets[nb - 1], get_len(nb - 1) + 9 + 1);
      add("last block length runs past the end", p, block_name(b, nb - 1), "runs past the end of the payload");
    }
    {
      auto p = b.payload;
      set_len(p, b.block_offsets[nb - 1], get_len(nb - 1) + 9);
      add("last block length swallows the end record", p, block_name(b, nb - 1), "checksum mismatch");
    }
    {
      // A shorter length with a matching hash: the block is intact, but its last record crosses its end.
      auto p = b.payload;
      set_len(p, b.block_offsets[1], get_len(1) - 3);
      rehash(p, b.block_offsets[1], get_len(1) - 3);
      const uint64_t last = b.block_first[2] - 1;
      add("a record crossing the end of its block", p, block_name(b, 1),
          "record " + std::to_string(last) + ": the record runs past the end of its block");
    }
    {
      // The end record inside the last block (its length and hash cover it).
      auto p = b.payload;
      set_len(p, b.block_offsets[nb - 1], get_len(nb - 1) + 9);
      rehash(p, b.block_offsets[nb - 1], get_len(nb - 1) + 9);
      add("the end record inside a block", p, block_name(b, nb - 1), "record tag 255 inside a block");
    }
    {
      auto p = b.payload;
      p.erase(p.begin() + long(b.block_offsets[1]), p.begin() + long(b.block_offsets[1] + 13));
      add("block 1's checksum record missing", p,
          "block 1 (records from " + std::to_string(b.block_first[1]) + ", payload byte " +
              std::to_string(b.block_offsets[1]) + ")",
          "expected a checksum record (tag 2) or the end record (tag 255), found tag 1");
    }
    {
      TraceHeader unflagged = b.h;
      unflagged.checksummed = false;
      add("a checksum record in a trace without the flag", b.payload, "record 0",
          "checksum record (tag 2) in a trace whose header does not flag checksums", &unflagged);
    }
    for (const Case& c : cases) {
      SCOPED_TRACE(std::string(to_string(z)) + ": " + c.what);
      const std::string path = tmp.path("bad.trace");
      write_file(path, assemble(c.h, c.payload));
      uint64_t handed = 0;
      const std::string msg = read_until_error(path, handed);
      if (msg.empty()) continue;
      expect_one_line_from(msg, path);
      EXPECT_EQ(msg.rfind(path + ": " + c.names, 0), 0u) << "error does not name " << c.names << ": " << msg;
      EXPECT_NE(msg.find(c.needle), std::string::npos) << "error lacks \"" << c.needle << "\": " << msg;
    }
  }
}

TEST(ChecksumReaderRefuses, UnknownHeaderFlags) {
  TempDir tmp;
  const TraceHeader h = make_ck_header(4, DepthMode::kPlane, ColorFormat::kRgbF32, Compression::kNone);
  const CkBuilt b = build_checksummed(h, make_fragments(h, 3, 1));
  for (uint16_t flags : {uint16_t(0x0004), uint16_t(0x0007), uint16_t(0x8000), uint16_t(0xFFFF)}) {
    std::vector<uint8_t> file = assemble(b.h, b.payload);
    file[10] = uint8_t(flags);
    file[11] = uint8_t(flags >> 8);
    const std::string path = tmp.path("flags.trace");
    write_file(path, file);
    char want[64];
    std::snprintf(want, sizeof want, "header: unknown flags 0x%04x", unsigned(flags & ~3u));
    expect_trace_error(path, -1, want, "flags " + std::to_string(flags));
  }
}

TEST(ChecksumReaderRefuses, AValidBlockIsVerifiedBeforeItsRecordsAreParsed) {
  // Block 1 holds a record with opacity 2 (invalid). With the hash recomputed
  // the block is intact and the record's own rule names it; with the stored hash
  // kept, the block fails its checksum first and none of its records is handed out.
  TempDir tmp;
  const TraceHeader h = make_ck_header(16, DepthMode::kPlane, ColorFormat::kRgbF32, Compression::kNone);
  auto frags = make_fragments(h, 4000, 3);
  CkBuilt ref = build_checksummed(h, frags);
  const uint64_t bad = ref.block_first[1] + 5;
  frags[bad].alpha = 2.0f;
  const CkBuilt b = build_checksummed(h, frags);  // hash over the bad record
  const std::string path = tmp.path("opacity.trace");
  write_file(path, assemble(b.h, b.payload));
  uint64_t handed = 0;
  std::string msg = read_until_error(path, handed);
  expect_one_line_from(msg, path);
  EXPECT_EQ(msg.rfind(path + ": " + block_name(b, 1) + ": record " + std::to_string(bad) + ": opacity", 0), 0u) << msg;
  EXPECT_EQ(handed, bad);
  // The same bytes under the original (now wrong) hash.
  std::vector<uint8_t> p = b.payload;
  std::copy(ref.payload.begin() + long(ref.block_offsets[1]) + 5, ref.payload.begin() + long(ref.block_offsets[1]) + 13,
            p.begin() + long(b.block_offsets[1]) + 5);
  write_file(path, assemble(b.h, p));
  msg = read_until_error(path, handed);
  EXPECT_EQ(msg.rfind(path + ": " + block_name(b, 1) + ": checksum mismatch", 0), 0u) << msg;
  EXPECT_EQ(handed, b.block_first[1]) << "records of a block were handed out before its checksum was verified";
}

TEST(ChecksumFormat, KeptRegressionInputs) {
  // fuzz/regressions/trace/ keeps a checksummed trace and the same trace with
  // one bit flipped in its only block (the fuzz target replays both).
  const fs::path dir = fs::path(ROPSIM_SOURCE_DIR) / "fuzz" / "regressions" / "trace";
  {
    TraceReader r((dir / "eight-layers-8x8-none-checksummed.rtrace").string());
    EXPECT_TRUE(r.header().checksummed);
    Fragment f;
    uint64_t n = 0;
    while (r.next(f)) ++n;
    EXPECT_EQ(n, 576u);
    EXPECT_EQ(r.blocks_read(), 1u);
  }
  const std::string flipped = (dir / "checksum-bit-flip-in-block.rtrace").string();
  uint64_t handed = 0;
  const std::string msg = read_until_error(flipped, handed);
  EXPECT_EQ(msg.rfind(flipped + ": block 0 (records from 0, payload byte 0): checksum mismatch", 0), 0u) << msg;
  EXPECT_EQ(handed, 0u);
}

// ------------------------------------------------------------------ the header's fragment count

/// Bytes 42..47 of a trace file set to `field` (the count + 1), the header check left as it is.
std::vector<uint8_t> with_count_field(std::vector<uint8_t> file, uint64_t field) {
  for (int i = 0; i < 6; ++i) file[size_t(42 + i)] = uint8_t(field >> (8 * i));
  return file;
}

uint64_t count_field(const std::vector<uint8_t>& file) {
  uint64_t v = 0;
  for (int i = 0; i < 6; ++i) v |= uint64_t(file[size_t(42 + i)]) << (8 * i);
  return v;
}

/// The message of the TraceError the reader's constructor throws, or "" (and
/// a failure) when the trace opens.
std::string open_error(const std::string& path) {
  try {
    TraceReader r(path);
    ADD_FAILURE() << path << ": opened, recording " << (r.recorded_fragments() ? *r.recorded_fragments() : 0)
                  << " fragments";
  } catch (const TraceError& e) {
    return e.what();
  }
  return "";
}

TEST(TraceHeaderCount, ACountThePayloadCannotHoldIsRefusedAtOpen) {
  // 2^48 - 2 fragments (the field's largest value, 2^48 - 1), and the count
  // with bit 47 (the top bit of byte 47) flipped: in traces without a header
  // check (older traces, --no-checksum) only the file's size bounds them.
  // They are refused when the reader opens the trace, before anything is
  // sized from them, in one line naming the file and the field.
  TempDir tmp;
  for (Compression z : {Compression::kNone, Compression::kZstd})
    for (bool checksummed : {false, true}) {
      TraceHeader h = make_header(16, DepthMode::kPlane, ColorFormat::kRgbF32, z);
      h.checksummed = checksummed;
      const std::string good = tmp.path("good.trace");
      {
        TraceWriter w(good, h);
        for (const auto& f : make_fragments(h, 500, 5)) w.write(f);
        w.finish();
      }
      std::vector<uint8_t> file = read_file(good);
      if (checksummed) {  // the same trace as a writer before the header check wrote it
        std::vector<uint8_t> old = encode_header_with(h, 500, false);
        const size_t checked = old.size() + kHeaderCheckBytes;
        old.insert(old.end(), file.begin() + long(checked), file.end());
        file = old;
      }
      for (uint64_t field : {(uint64_t{1} << 48) - 1, count_field(file) ^ (uint64_t{1} << 47)}) {
        SCOPED_TRACE(std::string(to_string(z)) + (checksummed ? ", checksummed" : "") + ", field " +
                     std::to_string(field));
        const std::string path = tmp.path("lie.trace");
        write_file(path, with_count_field(file, field));
        const std::string msg = open_error(path);
        expect_one_line_from(msg, path);
        EXPECT_NE(msg.find(": header: fragment count (bytes 42..47) " + std::to_string(field - 1) + " is more than"),
                  std::string::npos)
            << msg;
      }
    }
}

TEST(TraceHeaderCount, TheBoundIsThePayloadsRoomForItsSmallestRecords) {
  // An uncompressed payload of n plane records (43 bytes at 16 spp) and the
  // end record holds exactly n: a count of n opens (and is held to the
  // records), n + 1 is refused at open. A zstd frame recording its content
  // size (ZSTD_compress does) bounds the count the same way; one that does not
  // (TraceWriter streams) by 32768 decompressed bytes per compressed byte.
  TempDir tmp;
  const TraceHeader h = make_header(16, DepthMode::kPlane, ColorFormat::kRgbF32, Compression::kNone);
  ASSERT_EQ(fragment_record_bytes(h, 1), 43u);
  std::vector<uint8_t> payload;
  const auto frags = make_fragments(h, 200, 9);
  for (const auto& f : frags) encode_fragment(payload, h, f);
  encode_end(payload, frags.size());
  EXPECT_EQ(max_fragments_in_payload(h, payload.size()), 200u);
  for (Compression z : {Compression::kNone, Compression::kZstd}) {
    TraceHeader hz = h;
    hz.compression = z;
    const std::string path = tmp.path("bound.trace");
    write_file(path, assemble(hz, payload, 200));
    EXPECT_EQ(TraceReader(path).recorded_fragments(), std::optional<uint64_t>(200)) << to_string(z);
    write_file(path, assemble(hz, payload, 201));
    const std::string msg = open_error(path);
    EXPECT_NE(msg.find("fragment count (bytes 42..47) 201 is more than"), std::string::npos) << msg;
    EXPECT_NE(msg.find("at most 200 records of 43 bytes or more"), std::string::npos) << msg;
    if (z == Compression::kZstd) {
      EXPECT_NE(msg.find("the content size of its zstd frame"), std::string::npos) << msg;
    }
  }
  // Streamed zstd, no content size: C compressed bytes bound the payload to 32768 C.
  TraceHeader hs = h;
  hs.compression = Compression::kZstd;
  const std::string streamed = tmp.path("streamed.trace");
  {
    TraceWriter w(streamed, hs);
    for (const auto& f : make_fragments(hs, 4000, 10)) w.write(f);  // 172,009 bytes: more than one 128 KiB piece
    w.finish();
  }
  const std::vector<uint8_t> file = read_file(streamed);
  const size_t header_bytes = 48 + 2 * 16 + h.scene_name.size();
  ASSERT_EQ(ZSTD_getFrameContentSize(file.data() + header_bytes, file.size() - header_bytes), ZSTD_CONTENTSIZE_UNKNOWN)
      << "a streamed frame records no content size";
  const uint64_t most = max_fragments_in_payload(hs, (file.size() - header_bytes) * kZstdMaxRatio);
  const std::string path = tmp.path("streamed-lie.trace");
  write_file(path, with_count_field(file, most + 1));
  EXPECT_EQ(TraceReader(path).recorded_fragments(), std::optional<uint64_t>(most))
      << "the largest count the bound allows";
  EXPECT_NE(read_all_error(path).find("the header records " + std::to_string(most)), std::string::npos)
      << "and the records hold it to the truth";
  write_file(path, with_count_field(file, most + 2));
  const std::string msg = open_error(path);
  EXPECT_NE(msg.find("the compressed payload's " + std::to_string(file.size() - header_bytes) + " bytes"),
            std::string::npos)
      << msg;
}

TEST(TraceHeaderCheck, EveryBitOfTheCountIsCovered) {
  // A checksummed trace carries the header check (flags bit 1): the XXH3-64
  // of the header's bytes, right after the scene name. Each of the 48 bits of
  // the count flipped, and any other header byte changed, fails it at open.
  TempDir tmp;
  for (Compression z : {Compression::kNone, Compression::kZstd}) {
    const TraceHeader h = make_ck_header(4, DepthMode::kPlane, ColorFormat::kRgbF32, z);
    const std::string good = tmp.path("checked.trace");
    {
      TraceWriter w(good, h);
      for (const auto& f : make_fragments(h, 50, 2)) w.write(f);
      w.finish();
    }
    const std::vector<uint8_t> file = read_file(good);
    const std::vector<uint8_t> want = encode_header(h, 50);
    ASSERT_EQ(want.size(), 48 + 2 * 4 + h.scene_name.size() + 8);
    EXPECT_EQ(ropsim_test::first_element_difference(
                  want, std::vector<uint8_t>(file.begin(), file.begin() + long(std::min(want.size(), file.size())))),
              "")
        << "the header and its check, as specified";
    EXPECT_TRUE(TraceReader(good).header_checked());
    const std::string path = tmp.path("flipped.trace");
    for (int bit = 0; bit < 48; ++bit) {
      std::vector<uint8_t> f = file;
      f[size_t(42 + bit / 8)] ^= uint8_t(1u << (bit % 8));
      write_file(path, f);
      const std::string msg = open_error(path);
      expect_one_line_from(msg, path);
      EXPECT_NE(msg.find(": header: header check mismatch"), std::string::npos) << "bit " << bit << ": " << msg;
    }
    for (size_t at :
         {size_t(24), size_t(48), want.size() - 9, want.size() - 1}) {  // clear colour, a position, the name, the check
      std::vector<uint8_t> f = file;
      f[at] ^= 0x01;
      write_file(path, f);
      EXPECT_NE(open_error(path).find("header check mismatch"), std::string::npos) << "byte " << at;
    }
  }
}

TEST(TraceHeaderCheck, TracesWithoutTheCheckStillRead) {
  // A checksummed trace of a writer before the header check (flags 1) and an
  // unchecksummed one (flags 0, what --no-checksum writes) both read, count
  // and all; the kept regression trace of flags 1 too.
  TempDir tmp;
  for (bool checksummed : {false, true}) {
    TraceHeader h = make_header(4, DepthMode::kPlane, ColorFormat::kRgbF32, Compression::kNone);
    h.checksummed = checksummed;
    const auto frags = make_fragments(h, 40, 8);
    std::vector<uint8_t> payload;
    if (checksummed) {
      payload = build_checksummed(h, frags).payload;
    } else {
      for (const auto& f : frags) encode_fragment(payload, h, f);
      encode_end(payload, frags.size());
    }
    std::vector<uint8_t> file = encode_header_with(h, frags.size(), false);
    EXPECT_EQ(file[10], checksummed ? 1 : 0);
    file.insert(file.end(), payload.begin(), payload.end());
    const std::string path = tmp.path("old.trace");
    write_file(path, file);
    TraceReader r(path);
    EXPECT_FALSE(r.header_checked());
    EXPECT_EQ(r.recorded_fragments(), std::optional<uint64_t>(40));
    Fragment f;
    uint64_t n = 0;
    while (r.next(f)) ++n;
    EXPECT_EQ(n, 40u);
    if (!checksummed) {  // the writer's --no-checksum layout is that one
      const std::string w = tmp.path("w.trace");
      {
        TraceWriter tw(w, h);
        for (const auto& x : frags) tw.write(x);
        tw.finish();
      }
      EXPECT_EQ(read_file(w), file);
    }
  }
  const fs::path kept =
      fs::path(ROPSIM_SOURCE_DIR) / "fuzz" / "regressions" / "trace" / "eight-layers-8x8-none-checksummed.rtrace";
  EXPECT_EQ(read_file(kept.string())[10], 1) << "the kept trace predates the header check";
  EXPECT_FALSE(TraceReader(kept.string()).header_checked());
}

}  // namespace
