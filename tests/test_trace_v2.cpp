// Trace format version 2 (docs/trace-format.md, section 1.5): the draw table.
// Round trips of every enumeration and a UTF-8 name, the writer's bytes
// against an encoder written here from the specification, version 1's bytes
// unchanged for an empty table (traces written by the version 1 writer are
// kept in tests/data), the reader's refusal of every bad field with one line
// naming the file and the record (through `ropsim trace validate` too), and
// the table carried by everything that carries a header.
#include <gtest/gtest.h>
#include <unistd.h>
#include <xxhash.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "rtl_models/functional/fragment_source.h"
#include "sim/fidelity/sampled/livepoint_file.h"
#include "sim/fidelity/sampled/livepoints.h"
#include "tests/compare_util.h"
#include "traces/format/trace.h"
#include "traces/raster/sample_patterns.h"
#include "util/memory_budget.h"

#ifndef ROPSIM_BINARY
#error "ROPSIM_BINARY must name the built ropsim executable (tests/CMakeLists.txt)"
#endif
#ifndef ROPSIM_SOURCE_DIR
#error "ROPSIM_SOURCE_DIR must name the source tree (tests/CMakeLists.txt)"
#endif

namespace fs = std::filesystem;
using namespace ropsim;

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

// ------------------------------------------------------------------ helpers

class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = std::string("ropsim-test-trace-v2-") + std::to_string(::getpid()) + "-" +
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

 private:
  fs::path dir_;
};

void write_file(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  ASSERT_TRUE(f.good()) << "cannot write " << path;
}

std::vector<uint8_t> read_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

struct CliResult {
  int code = -1;
  std::string out, err;
  std::string describe() const { return "exit " + std::to_string(code) + "\nstdout:\n" + out + "stderr:\n" + err; }
};

/// Runs `ropsim ARGS` (through /bin/sh) with its output captured in dir.
CliResult run_ropsim(const TempDir& dir, const std::string& args) {
  const std::string out = dir.path("cli.stdout"), err = dir.path("cli.stderr");
  const std::string cmd = "'" ROPSIM_BINARY "' " + args + " >'" + out + "' 2>'" + err + "' </dev/null";
  const int st = std::system(cmd.c_str());
  CliResult r;
  r.code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  const auto slurp = [](const std::string& p) {
    std::ifstream f(p, std::ios::binary);
    std::ostringstream s;
    s << f.rdbuf();
    return s.str();
  };
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
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
void putf(std::vector<uint8_t>& o, float f) {
  uint32_t b;
  std::memcpy(&b, &f, 4);
  put32(o, b);
}

/// A draw-state record as raw bytes (section 1.5), fields settable beyond
/// what DrawState's enumerations hold.
struct RawDrawRecord {
  uint32_t draw_id = 0;
  uint8_t flags = 0x03;  // blend, depth test
  uint8_t eq_rgb = 0, eq_alpha = 0, src_rgb = 6, dst_rgb = 7, src_alpha = 1, dst_alpha = 7, depth_func = 1;
  uint8_t color_mask = 0xF, encoding = 2;
  float blend_color[4] = {0, 0, 0, 0};
  std::string name;
  int name_len = -1;  ///< the length byte; -1: name.size()
};

RawDrawRecord raw_of(const DrawState& s) {
  RawDrawRecord r;
  r.draw_id = s.draw_id;
  r.flags = uint8_t((s.blend ? 1 : 0) | (s.depth_test ? 2 : 0) | (s.depth_write ? 4 : 0));
  r.eq_rgb = uint8_t(s.eq_rgb);
  r.eq_alpha = uint8_t(s.eq_alpha);
  r.src_rgb = uint8_t(s.src_rgb);
  r.dst_rgb = uint8_t(s.dst_rgb);
  r.src_alpha = uint8_t(s.src_alpha);
  r.dst_alpha = uint8_t(s.dst_alpha);
  r.depth_func = uint8_t(s.depth_func);
  r.color_mask = s.color_mask;
  r.encoding = uint8_t(s.encoding);
  for (int i = 0; i < 4; ++i) r.blend_color[i] = s.blend_color[size_t(i)];
  r.name = s.name;
  return r;
}

void encode_draw_record(std::vector<uint8_t>& o, const RawDrawRecord& r) {
  put32(o, r.draw_id);                                                    // +0
  put8(o, r.flags);                                                       // +4
  put8(o, r.eq_rgb);                                                      // +5
  put8(o, r.eq_alpha);                                                    // +6
  put8(o, r.src_rgb);                                                     // +7
  put8(o, r.dst_rgb);                                                     // +8
  put8(o, r.src_alpha);                                                   // +9
  put8(o, r.dst_alpha);                                                   // +10
  put8(o, r.depth_func);                                                  // +11
  put8(o, r.color_mask);                                                  // +12
  put8(o, r.encoding);                                                    // +13
  for (float c : r.blend_color) putf(o, c);                               // +14, 18, 22, 26
  put8(o, uint8_t(r.name_len < 0 ? r.name.size() : size_t(r.name_len)));  // +30
  o.insert(o.end(), r.name.begin(), r.name.end());                        // +31
}

/// A version 2 header: version 1's fixed part (version 2), positions, name,
/// the draw table (count, then the records), and with `check` the header check.
std::vector<uint8_t> encode_v2_header(const TraceHeader& h, const std::vector<RawDrawRecord>& records, bool check,
                                      std::optional<uint64_t> count = std::nullopt,
                                      std::optional<uint32_t> draw_count = std::nullopt, uint16_t version = 2) {
  std::vector<uint8_t> o;
  for (char c : kTraceMagic) o.push_back(uint8_t(c));
  put16(o, version);
  put16(o, uint16_t((h.checksummed ? 1 : 0) | (check ? 2 : 0)));
  put32(o, h.width);
  put32(o, h.height);
  put8(o, uint8_t(h.spp));
  put8(o, uint8_t(h.depth_mode));
  put8(o, uint8_t(h.color_format));
  put8(o, uint8_t(h.compression));
  for (float c : h.clear_color) putf(o, c);
  putf(o, h.clear_depth);
  put16(o, uint16_t(h.scene_name.size()));
  for (int i = 0; i < 6; ++i) put8(o, count ? uint8_t((*count + 1) >> (8 * i)) : 0);
  for (int i = 0; i < h.spp; ++i) {
    put8(o, h.positions[size_t(i)].x);
    put8(o, h.positions[size_t(i)].y);
  }
  o.insert(o.end(), h.scene_name.begin(), h.scene_name.end());
  put32(o, draw_count ? *draw_count : uint32_t(records.size()));
  for (const auto& r : records) encode_draw_record(o, r);
  if (check) put64(o, XXH3_64bits(o.data(), o.size()));
  return o;
}

/// A plane-depth, rgb-f32 fragment record.
void encode_fragment(std::vector<uint8_t>& o, const TraceHeader& h, const Fragment& f) {
  put8(o, kTagFragment);
  put32(o, f.draw_id);
  put32(o, f.prim_id);
  put16(o, f.x);
  put16(o, f.y);
  for (int i = 0; i < (h.spp + 7) / 8; ++i) put8(o, uint8_t(f.coverage >> (8 * i)));
  putf(o, f.z0);
  putf(o, f.dzdx);
  putf(o, f.dzdy);
  for (float c : f.rgb) putf(o, c);
  putf(o, f.alpha);
}

/// An uncompressed, unchecksummed, plane-depth rgb-f32 header.
TraceHeader plain_header(int spp = 4, uint32_t w = 8, uint32_t h = 4) {
  TraceHeader t;
  t.width = w;
  t.height = h;
  t.spp = spp;
  t.depth_mode = DepthMode::kPlane;
  t.color_format = ColorFormat::kRgbF32;
  t.compression = Compression::kNone;
  t.checksummed = false;
  t.positions = standard_sample_positions(spp);
  t.scene_name = "v2";
  return t;
}

Fragment frag(uint32_t draw, uint16_t x, uint16_t y, uint64_t coverage, float alpha = 0.5f) {
  Fragment f;
  f.draw_id = draw;
  f.prim_id = 7;
  f.x = x;
  f.y = y;
  f.coverage = coverage;
  f.z0 = 0.25f;
  f.rgb = {0.1f, 0.2f, 0.3f};
  f.alpha = alpha;
  return f;
}

/// A whole uncompressed, unchecksummed trace: header, records, end record.
std::vector<uint8_t> encode_trace(const TraceHeader& h, const std::vector<RawDrawRecord>& records,
                                  const std::vector<Fragment>& frags) {
  std::vector<uint8_t> o = encode_v2_header(h, records, false);
  for (const Fragment& f : frags) encode_fragment(o, h, f);
  put8(o, kTagEnd);
  put64(o, frags.size());
  return o;
}

/// States that between them take every value of every enumeration, each
/// flag both ways, masks 0..15, and names: empty, ASCII, multi-byte UTF-8 and
/// 255 bytes.
std::vector<DrawState> every_enumeration() {
  std::vector<DrawState> v;
  const int n = 16;  // >= every enumeration's size (15 factors, 5 equations, 8 functions, 3 encodings)
  for (int i = 0; i < n; ++i) {
    DrawState s;
    s.draw_id = uint32_t(3 * i + (i % 3));  // sparse ids
    s.blend = i % 2 == 0;
    s.depth_test = i % 3 != 0;
    s.depth_write = i % 4 == 1;
    s.eq_rgb = BlendEquation(i % 5);
    s.eq_alpha = BlendEquation((i + 2) % 5);
    s.src_rgb = BlendFactor(i % 15);
    s.dst_rgb = BlendFactor((i + 4) % 15);
    s.src_alpha = BlendFactor((i + 8) % 15);
    s.dst_alpha = BlendFactor((i + 12) % 15);
    s.depth_func = DepthFunc(i % 8);
    s.color_mask = uint8_t(i % 16);
    s.encoding = TargetEncoding(i % 3);
    s.blend_color = {0.25f * float(i), -1.5f, 1e30f, float(i) / 7.0f};
    switch (i % 4) {
      case 0:
        s.name = "";
        break;
      case 1:
        s.name = "program " + std::to_string(i);
        break;
      case 2:
        s.name = "Glas \xE2\x80\x93 \xE7\x8E\xBB\xE7\x92\x83 \xF0\x9F\x8D\xB7";  // "Glas – 玻璃 🍷"
        break;
      default:
        s.name = std::string(255, 'n');
        break;
    }
    v.push_back(s);
  }
  return v;
}

std::string first_line(const std::string& s) { return s.substr(0, s.find('\n')); }

// ------------------------------------------------------------------ round trips and bytes

TEST(TraceV2, RoundTripOfEveryEnumerationAndAUtf8Name) {
  TempDir tmp;
  const std::vector<DrawState> states = every_enumeration();
  for (Compression z : {Compression::kNone, Compression::kZstd})
    for (bool checksummed : {false, true})
      for (DepthMode d : {DepthMode::kPlane, DepthMode::kPerSample}) {
        TraceHeader h = plain_header(8);
        h.compression = z;
        h.checksummed = checksummed;
        h.depth_mode = d;
        h.draws = DrawTable(states);
        std::vector<Fragment> frags;
        for (size_t i = 0; i < 3 * states.size(); ++i) {
          Fragment f = frag(states[i % states.size()].draw_id, uint16_t(i % 8), uint16_t(i / 8 % 4), 0x5A);
          for (int s = 0; s < 8; ++s) f.z[size_t(s)] = float(s) / 8.0f;
          frags.push_back(f);
        }
        const std::string path = tmp.path("rt.trace");
        {
          TraceWriter w(path, h);
          for (const Fragment& f : frags) w.write(f);
          w.finish();
        }
        const std::string what = std::string(to_string(z)) + (checksummed ? " checksummed " : " ") + to_string(d);
        EXPECT_EQ(read_file(path)[8], 2) << what << ": a non-empty table writes version 2";
        TraceReader r(path);
        EXPECT_EQ(r.version(), 2) << what;
        EXPECT_EQ(r.header().version(), 2) << what;
        EXPECT_EQ(r.header_checked(), checksummed) << what << ": a checksummed v2 trace checks its header";
        ASSERT_EQ(r.header().draws.size(), states.size()) << what;
        EXPECT_EQ(ropsim_test::first_draw_table_difference(r.header().draws, h.draws), "")
            << what << ": the table read back differs";
        for (const DrawState& s : states) {
          const DrawState* got = r.header().draws.find(s.draw_id);
          ASSERT_NE(got, nullptr) << what << ": draw " << s.draw_id;
          EXPECT_EQ(got->name, s.name) << what;
          EXPECT_EQ(draw_kind(*got), draw_kind(s)) << what;
        }
        Fragment f;
        size_t i = 0;
        while (r.next(f)) {
          ASSERT_LT(i, frags.size()) << what;
          EXPECT_EQ(f.draw_id, frags[i].draw_id) << what << " record " << i;
          EXPECT_EQ(f.coverage, frags[i].coverage) << what << " record " << i;
          ++i;
        }
        EXPECT_EQ(i, frags.size()) << what;
      }
}

TEST(TraceV2, WriterBytesMatchTheSpecification) {
  TempDir tmp;
  TraceHeader h = plain_header(4);
  const std::vector<DrawState> states = every_enumeration();
  h.draws = DrawTable(states);
  std::vector<Fragment> frags = {frag(states[0].draw_id, 1, 1, 0x3), frag(states[5].draw_id, 2, 3, 0xF)};
  const std::string path = tmp.path("spec.trace");
  {
    TraceWriter w(path, h);
    for (const Fragment& f : frags) w.write(f);
    w.finish();
  }
  std::vector<RawDrawRecord> records;
  for (const DrawState& s : h.draws.states()) records.push_back(raw_of(s));
  std::vector<uint8_t> want = encode_v2_header(h, records, false, frags.size());
  for (const Fragment& f : frags) encode_fragment(want, h, f);
  put8(want, kTagEnd);
  put64(want, frags.size());
  const std::vector<uint8_t> got = read_file(path);
  ASSERT_EQ(got.size(), want.size()) << "file size";
  size_t first_diff = 0;
  while (first_diff < got.size() && got[first_diff] == want[first_diff]) ++first_diff;
  EXPECT_EQ(first_diff, got.size()) << "first differing byte at offset " << first_diff;
  // The table's records lie in draw-id order, each kDrawRecordFixedBytes + its name.
  size_t table = 0;
  for (const DrawState& s : states) table += kDrawRecordFixedBytes + s.name.size();
  EXPECT_EQ(got.size(), 48 + 2 * 4 + h.scene_name.size() + 4 + table + frags.size() * 42 + 9);
}

TEST(TraceV2, TheHeaderCheckCoversTheDrawTable) {
  // Every byte of the table of a checksummed trace is under the header check:
  // flipping any bit of it is refused at open, naming the check.
  TempDir tmp;
  TraceHeader h = plain_header(4);
  h.checksummed = true;
  DrawState s = default_draw_state(9);
  s.name = "glass";
  h.draws = DrawTable({s});
  const std::string path = tmp.path("checked.trace");
  {
    TraceWriter w(path, h);
    w.write(frag(9, 0, 0, 1));
    w.finish();
  }
  const std::vector<uint8_t> good = read_file(path);
  const size_t table_at = 48 + 2 * 4 + h.scene_name.size(), table_end = table_at + 4 + kDrawRecordFixedBytes + 5;
  int refused = 0;
  for (size_t at = table_at; at < table_end; ++at)
    for (int bit = 0; bit < 8; ++bit) {
      std::vector<uint8_t> bad = good;
      bad[at] ^= uint8_t(1u << bit);
      const std::string p = tmp.path("flip.trace");
      write_file(p, bad);
      try {
        TraceReader r(p);
        Fragment f;
        while (r.next(f)) {
        }
        ADD_FAILURE() << "byte " << at << " bit " << bit << " flipped: read without an error";
      } catch (const TraceError& e) {
        ++refused;
        EXPECT_EQ(std::string(e.what()).rfind(p + ": header: ", 0), 0u) << e.what();
      }
    }
  EXPECT_EQ(refused, int(8 * (table_end - table_at)));
  // Flipping a table byte and recomputing nothing is refused by the check
  // itself when the table still parses (a bit of the blend colour).
  std::vector<uint8_t> bad = good;
  bad[table_at + 4 + 14] ^= 1;
  write_file(tmp.path("colour.trace"), bad);
  try {
    TraceReader r(tmp.path("colour.trace"));
    ADD_FAILURE() << "a flipped blend-colour bit was not refused";
  } catch (const TraceError& e) {
    EXPECT_NE(std::string(e.what()).find("header check mismatch"), std::string::npos) << e.what();
  }
}

TEST(TraceV2, AnEmptyTableWritesVersion1ByteForByte) {
  // tests/data/v1-*.trace were written by the version 1 writer, before draw
  // tables existed: `ropsim scene testcard --spp 4 --width 40 --height 24`
  // (zstd, checksummed) and `... --width 20 --height 12 --depth per-sample
  // --compression none --no-checksum`. Read and rewritten through TraceReader
  // and TraceWriter, their bytes must come out unchanged: the table is empty,
  // so the writer writes version 1.
  TempDir tmp;
  const std::string dir = std::string(ROPSIM_SOURCE_DIR) + "/tests/data/";
  for (const char* name : {"v1-testcard-zstd-checksummed.trace", "v1-testcard-per-sample-raw.trace"}) {
    const std::string in = dir + name, out = tmp.path(name);
    ASSERT_TRUE(fs::exists(in)) << in;
    {
      TraceReader r(in);
      EXPECT_EQ(r.version(), 1) << name;
      EXPECT_TRUE(r.header().draws.empty()) << name;
      EXPECT_EQ(r.header().version(), 1) << name;
      TraceWriter w(out, r.header());
      Fragment f;
      while (r.next(f)) w.write(f);
      w.finish();
    }
    const std::vector<uint8_t> want = read_file(in), got = read_file(out);
    ASSERT_EQ(got.size(), want.size()) << name << ": file size";
    size_t first_diff = 0;
    while (first_diff < got.size() && got[first_diff] == want[first_diff]) ++first_diff;
    EXPECT_EQ(first_diff, got.size()) << name << ": first differing byte at offset " << first_diff;
  }
}

TEST(TraceV2, TheJsonHeaderShowsTheTable) {
  TraceHeader h = plain_header(4);
  EXPECT_EQ(nlohmann::json::parse(header_to_json(h))["draws"], nlohmann::json::array()) << "version 1: no states";
  EXPECT_EQ(nlohmann::json::parse(header_to_json(h))["version"], 1);
  DrawState a = default_draw_state(4);
  a.blend = false;
  a.name = "\xE7\x8E\xBB\xE7\x92\x83";
  DrawState b = default_draw_state(2);
  b.src_rgb = BlendFactor::kOne;
  b.dst_rgb = BlendFactor::kOne;
  b.depth_func = DepthFunc::kGequal;
  b.encoding = TargetEncoding::kSrgb8;
  h.draws = DrawTable({a, b});
  const auto j = nlohmann::json::parse(header_to_json(h));
  EXPECT_EQ(j["version"], 2);
  ASSERT_EQ(j["draws"].size(), 2u);
  EXPECT_EQ(j["draws"][0]["draw"], 2) << "in draw-id order";
  EXPECT_EQ(j["draws"][0]["kind"], "additive");
  EXPECT_EQ(j["draws"][0]["src_rgb"], "ONE");
  EXPECT_EQ(j["draws"][0]["depth_func"], "GEQUAL");
  EXPECT_EQ(j["draws"][0]["encoding"], "srgb8");
  EXPECT_EQ(j["draws"][1]["kind"], "opaque");
  EXPECT_EQ(j["draws"][1]["name"], a.name);
  EXPECT_EQ(j["draws"][1]["blend"], false);
}

// ------------------------------------------------------------------ refusals

struct BadField {
  const char* what;
  std::function<void(RawDrawRecord&)> spoil;
  const char* message;  ///< what the one-line error says after "draw state 1 (draw 5): "
};

TEST(TraceV2Refuses, EachBadFieldWithOneLineThroughTheCli) {
  TempDir tmp;
  const TraceHeader h = plain_header(4);
  const std::vector<BadField> cases = {
      {"flags", [](RawDrawRecord& r) { r.flags = 0x08; }, "unknown flags 0x08"},
      {"eq_rgb", [](RawDrawRecord& r) { r.eq_rgb = 5; }, "blend equation out of range"},
      {"eq_alpha", [](RawDrawRecord& r) { r.eq_alpha = 255; }, "blend equation out of range"},
      {"src_rgb", [](RawDrawRecord& r) { r.src_rgb = 15; }, "blend factor out of range"},
      {"dst_rgb", [](RawDrawRecord& r) { r.dst_rgb = 200; }, "blend factor out of range"},
      {"src_alpha", [](RawDrawRecord& r) { r.src_alpha = 15; }, "blend factor out of range"},
      {"dst_alpha", [](RawDrawRecord& r) { r.dst_alpha = 16; }, "blend factor out of range"},
      {"depth_func", [](RawDrawRecord& r) { r.depth_func = 8; }, "depth function out of range"},
      {"color_mask", [](RawDrawRecord& r) { r.color_mask = 16; }, "colour mask above 15"},
      {"encoding", [](RawDrawRecord& r) { r.encoding = 3; }, "target encoding out of range"},
      {"blend_color NaN", [](RawDrawRecord& r) { r.blend_color[1] = kNaN; }, "blend colour not finite"},
      {"blend_color inf", [](RawDrawRecord& r) { r.blend_color[3] = -kInf; }, "blend colour not finite"},
      {"name not UTF-8", [](RawDrawRecord& r) { r.name = "a\xC0\x80"; }, "name is not valid UTF-8"},
      {"name a lone continuation byte", [](RawDrawRecord& r) { r.name = "\x80"; }, "name is not valid UTF-8"},
      {"draw id repeated", [](RawDrawRecord& r) { r.draw_id = 2; }, "a second state for the same draw"},
      {"draw id out of order", [](RawDrawRecord& r) { r.draw_id = 1; }, "draw ids out of order"},
  };
  for (const BadField& c : cases) {
    RawDrawRecord a, b, last;
    a.draw_id = 2;
    b.draw_id = 5;
    last.draw_id = 9;
    b.name = "glass";
    c.spoil(b);
    const std::string path = tmp.path("bad.trace");
    write_file(path, encode_trace(h, {a, b, last}, {frag(2, 0, 0, 1)}));
    const CliResult r = run_ropsim(tmp, "trace validate '" + path + "'");
    EXPECT_EQ(r.code, 1) << c.what << "\n" << r.describe();
    EXPECT_EQ(r.out, "") << c.what;
    const std::string want =
        "ropsim: error: " + path + ": header: draw state 1 (draw " + std::to_string(b.draw_id) + "): " + c.message;
    EXPECT_EQ(r.err.rfind(want, 0), 0u) << c.what << ": expected " << want << "\n" << r.describe();
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << c.what << ": one line\n" << r.err;
  }
  // The same trace unspoiled is valid.
  RawDrawRecord a, b, last;
  a.draw_id = 2;
  b.draw_id = 5;
  last.draw_id = 9;
  write_file(tmp.path("good.trace"), encode_trace(h, {a, b, last}, {frag(2, 0, 0, 1), frag(9, 1, 0, 3)}));
  const CliResult ok = run_ropsim(tmp, "trace validate '" + tmp.path("good.trace") + "'");
  EXPECT_EQ(ok.code, 0) << ok.describe();
}

TEST(TraceV2Refuses, TruncationInsideTheTable) {
  TempDir tmp;
  const TraceHeader h = plain_header(4);
  RawDrawRecord a;
  a.name = "glass";
  const std::vector<uint8_t> whole = encode_trace(h, {a}, {});
  const size_t table_at = 48 + 8 + h.scene_name.size();
  const std::map<size_t, std::string> cut = {
      {table_at + 2, "truncated in the draw count"},
      {table_at + 4 + 10, "truncated in draw state 0"},
      {table_at + 4 + kDrawRecordFixedBytes + 2, "truncated in draw state 0's name"}};
  for (const auto& [size, message] : cut) {
    const std::string path = tmp.path("cut.trace");
    write_file(path, std::vector<uint8_t>(whole.begin(), whole.begin() + long(size)));
    try {
      TraceReader r(path);
      ADD_FAILURE() << size << " bytes: opened";
    } catch (const TraceError& e) {
      EXPECT_NE(std::string(e.what()).find(path + ": header: "), std::string::npos) << e.what();
      // A short file's draw count is refused by the bound first, or the read runs out.
      const std::string w = e.what();
      EXPECT_TRUE(w.find(message) != std::string::npos || w.find("draw count") != std::string::npos)
          << size << " bytes: " << w;
    }
  }
}

TEST(TraceV2Refuses, ADrawCountTheFileCannotHoldAtOpen) {
  // The count is bounded by the bytes after it (kDrawRecordFixedBytes per
  // state at least): a damaged count is refused before any state is read or
  // any memory is taken for them.
  TempDir tmp;
  const TraceHeader h = plain_header(4);
  RawDrawRecord a;
  for (uint32_t count : {2u, 1000u, 0xFFFFFFFFu}) {
    std::vector<uint8_t> bytes = encode_v2_header(h, {a}, false, std::nullopt, count);
    put8(bytes, kTagEnd);
    put64(bytes, 0);
    const std::string path = tmp.path("count.trace");
    write_file(path, bytes);
    const uint64_t room = kDrawRecordFixedBytes;  // one record after the count, then the end record
    try {
      TraceReader r(path);
      ADD_FAILURE() << "draw count " << count << ": opened";
    } catch (const TraceError& e) {
      const std::string want = path + ": header: draw count " + std::to_string(count) + " is more than the file's " +
                               std::to_string(room) + " bytes after it can hold (at most 1 records of " +
                               std::to_string(kDrawRecordFixedBytes) + " bytes or more)";
      EXPECT_EQ(std::string(e.what()).rfind(want, 0), 0u) << e.what() << "\nwant: " << want;
    }
  }
  // Through the CLI: one line, exit 1.
  const CliResult r = run_ropsim(tmp, "trace info '" + tmp.path("count.trace") + "'");
  EXPECT_EQ(r.code, 1) << r.describe();
  EXPECT_NE(r.err.find("draw count 4294967295"), std::string::npos) << r.describe();
}

TEST(TraceV2Refuses, AFragmentOfADrawTheTableLacks) {
  TempDir tmp;
  TraceHeader h = plain_header(4);
  RawDrawRecord a, b;
  a.draw_id = 0;
  b.draw_id = 2;
  const std::string path = tmp.path("unknown.trace");
  write_file(path, encode_trace(h, {a, b}, {frag(0, 0, 0, 1), frag(2, 1, 0, 1), frag(1, 2, 0, 1)}));
  const CliResult r = run_ropsim(tmp, "trace validate '" + path + "'");
  EXPECT_EQ(r.code, 1) << r.describe();
  EXPECT_EQ(first_line(r.err),
            "ropsim: error: " + path + ": record 2: draw 1 has no state in the header's draw table (2 states)")
      << r.describe();
  // The writer refuses it too, and leaves no file.
  h.draws = DrawTable({default_draw_state(0), default_draw_state(2)});
  const std::string out = tmp.path("written.trace");
  {
    TraceWriter w(out, h);
    w.write(frag(2, 0, 0, 1));
    try {
      w.write(frag(3, 0, 0, 1));
      ADD_FAILURE() << "the writer took a fragment of draw 3";
    } catch (const TraceError& e) {
      EXPECT_EQ(std::string(e.what()), out + ": record 1: draw 3 has no state in the header's draw table (2 states)");
    }
  }
  EXPECT_FALSE(fs::exists(out));
}

TEST(TraceV2Refuses, AChecksummedVersion2TraceWithoutItsHeaderCheck) {
  TempDir tmp;
  TraceHeader h = plain_header(4);
  h.checksummed = true;
  std::vector<uint8_t> bytes = encode_v2_header(h, {RawDrawRecord{}}, false);
  put8(bytes, kTagEnd);
  put64(bytes, 0);
  const std::string path = tmp.path("unchecked.trace");
  write_file(path, bytes);
  try {
    TraceReader r(path);
    ADD_FAILURE() << "opened";
  } catch (const TraceError& e) {
    EXPECT_NE(std::string(e.what()).find("must check its header (flag bit 1)"), std::string::npos) << e.what();
  }
  // Version 3 is unknown.
  write_file(path, encode_v2_header(plain_header(4), {}, false, std::nullopt, std::nullopt, 3));
  try {
    TraceReader r(path);
    ADD_FAILURE() << "opened version 3";
  } catch (const TraceError& e) {
    EXPECT_EQ(std::string(e.what()), path + ": header: unsupported version 3 (this reader reads 1 and 2)");
  }
}

TEST(TraceV2Refuses, TheWriterRefusesABadTable) {
  TempDir tmp;
  TraceHeader h = plain_header(4);
  DrawState s = default_draw_state(1);
  s.name = std::string(256, 'x');
  h.draws = DrawTable({s});
  const std::string path = tmp.path("w.trace");
  try {
    TraceWriter w(path, h);
    ADD_FAILURE() << "a 256-byte name was written";
  } catch (const TraceError& e) {
    EXPECT_EQ(std::string(e.what()), path + ": header: draw state 0 (draw 1): name longer than 255 bytes");
  }
  h.draws = DrawTable({default_draw_state(1), default_draw_state(1)});
  try {
    TraceWriter w(path, h);
    ADD_FAILURE() << "two states of draw 1 were written";
  } catch (const TraceError& e) {
    EXPECT_EQ(std::string(e.what()), path + ": header: draw state 1 (draw 1): a second state for the same draw");
  }
  EXPECT_FALSE(fs::exists(path));
}

TEST(TraceV2, TheTableIsChargedToTheMemoryBudget) {
  TempDir tmp;
  TraceHeader h = plain_header(4);
  std::vector<DrawState> states;
  for (uint32_t i = 0; i < 20000; ++i) states.push_back(default_draw_state(i));
  h.draws = DrawTable(states);
  const std::string path = tmp.path("many.trace");
  {
    TraceWriter w(path, h);
    w.finish();
  }
  const uint64_t before = memory_budget().used(), limit = memory_budget().limit();
  {
    TraceReader r(path);
    EXPECT_GE(memory_budget().used(), before + 20000 * sizeof(DrawState)) << "the table was not charged";
  }
  EXPECT_EQ(memory_budget().used(), before) << "the reader kept its share after it closed";
  memory_budget().set_limit(before + 1000 * sizeof(DrawState));
  try {
    TraceReader r(path);
    ADD_FAILURE() << "a table over the memory limit was read";
  } catch (const UserError& e) {
    EXPECT_NE(std::string(e.what()).find("the draw table of " + path), std::string::npos) << e.what();
  }
  memory_budget().set_limit(limit);
  EXPECT_EQ(memory_budget().used(), before);
}

// ------------------------------------------------------------------ carried by what carries a header

TEST(TraceV2, FragmentSourcesCarryTheTable) {
  TempDir tmp;
  TraceHeader h = plain_header(4);
  DrawState glass = default_draw_state(3);
  glass.name = "glass";
  DrawState wall = default_draw_state(1);
  wall.blend = false;
  h.draws = DrawTable({glass, wall});
  const std::string path = tmp.path("src.trace");
  {
    TraceWriter w(path, h);
    w.write(frag(1, 0, 0, 0xF, 1.0f));
    w.write(frag(3, 0, 0, 0x3));
    w.finish();
  }
  InputSpec in;
  in.trace_path = path;
  in.repeat = 3;
  auto src = open_fragments(in);
  EXPECT_EQ(ropsim_test::first_draw_table_difference(src->header().draws, h.draws), "") << "the trace's source";
  Fragment f;
  uint64_t n = 0;
  while (src->next(f)) {
    ++n;
    EXPECT_NE(src->header().draws.find(f.draw_id), nullptr) << "a repeat's draw ids are the table's";
  }
  EXPECT_EQ(n, 6u);
  EXPECT_EQ(ropsim_test::first_draw_table_difference(src->header().draws, h.draws), "") << "after the repeats";
  const std::vector<Fragment> held = {frag(3, 1, 1, 1)};
  EXPECT_EQ(ropsim_test::first_draw_table_difference(fragments_from(h, held)->header().draws, h.draws), "")
      << "fragments_from";
}

TEST(TraceV2, TheLivePointLibraryCarriesTheTable) {
  TempDir tmp;
  // A v2 trace of a scene: the scene's fragments with a table of two draws.
  SceneParams sp;
  sp.name = "testcard";
  sp.spp = 4;
  sp.width = 64;
  sp.height = 48;
  Scene scene = build_scene(sp);
  TraceHeader h = scene.header;
  std::set<uint32_t> ids;
  rasterize_scene(scene, [&](const Fragment& f) { ids.insert(f.draw_id); });
  std::vector<DrawState> states;
  for (uint32_t id : ids) {
    // Src-over and premultiplied-over draws, each with its own name and
    // depth state.
    DrawState s = default_draw_state(id);
    if (id % 2) s.src_rgb = BlendFactor::kOne;
    s.depth_func = id % 2 ? DepthFunc::kLequal : DepthFunc::kLess;
    s.name = "draw \xCE\xB1" + std::to_string(id);
    states.push_back(s);
  }
  h.draws = DrawTable(states);
  const std::string trace = tmp.path("lp.trace");
  {
    TraceWriter w(trace, h);
    rasterize_scene(scene, [&](const Fragment& f) { w.write(f); });
    w.finish();
  }
  InputSpec in;
  in.trace_path = trace;
  SamplingParams p;
  p.units = 2;
  p.unit_fragments = 200;
  const LivePoints lib = record_livepoints(in, GoldenConfig{}, p);
  EXPECT_EQ(ropsim_test::first_draw_table_difference(lib.header.draws, h.draws), "") << "the recorded library";
  {  // a frame with an opaque draw is recorded; slab, which draws it in a pre-pass, is refused
    TraceHeader ho = h;
    std::vector<DrawState> so = states;
    so.front().blend = false;
    ho.draws = DrawTable(so);
    const std::string opaque_trace = tmp.path("opaque.trace");
    {
      TraceWriter w(opaque_trace, ho);
      rasterize_scene(scene, [&](const Fragment& f) { w.write(f); });
      w.finish();
    }
    InputSpec io;
    io.trace_path = opaque_trace;
    EXPECT_EQ(ropsim_test::first_draw_table_difference(record_livepoints(io, GoldenConfig{}, p).header.draws, ho.draws),
              "");
    GoldenConfig slab;
    slab.method = Method::kSlab;
    try {
      record_livepoints(io, slab, p);
      ADD_FAILURE() << "slab was recorded on a frame with an opaque draw";
    } catch (const UserError& e) {
      EXPECT_NE(std::string(e.what()).find("pre-pass"), std::string::npos) << e.what();
    }
  }
  const std::string file = tmp.path("lib.rlp");
  write_livepoints(file, lib);
  const LivePoints back = read_livepoints(file);
  EXPECT_EQ(ropsim_test::first_draw_table_difference(back.header.draws, h.draws), "") << "the library read back";
  EXPECT_FALSE(back.header.draws.empty());
  // Version 1 libraries (without the table) are refused in one line.
  std::vector<uint8_t> bytes = read_file(file);
  bytes[8] = 1;
  write_file(file, bytes);
  try {
    read_livepoints(file);
    ADD_FAILURE() << "a version 1 library was read";
  } catch (const UserError& e) {
    EXPECT_EQ(std::string(e.what()), file + ": live-point library version 1, this ropsim reads " +
                                         std::to_string(kLivePointFileVersion) +
                                         " (rebuild it with `ropsim livepoints`)");
  }
}

// ------------------------------------------------------------------ trace info by kind

TEST(TraceV2Info, DrawsByKindAndTheTransparentShare) {
  // A hand-built 4x2 trace at 4 spp with a draw of every kind (and a
  // src-over draw without fragments); the expected figures are computed
  // here from the fragments.
  TempDir tmp;
  TraceHeader h = plain_header(4, 4, 2);
  DrawState opaque = default_draw_state(0);
  opaque.blend = false;
  DrawState over = default_draw_state(1);
  DrawState premul = default_draw_state(2);
  premul.src_rgb = BlendFactor::kOne;
  DrawState add = default_draw_state(3);
  add.src_rgb = BlendFactor::kOne;
  add.dst_rgb = BlendFactor::kOne;
  DrawState other = default_draw_state(4);
  other.eq_rgb = BlendEquation::kMin;
  DrawState unused = default_draw_state(5);
  h.draws = DrawTable({opaque, over, premul, add, other, unused});
  const DrawKind kinds[] = {DrawKind::kOpaque,   DrawKind::kSrcOver, DrawKind::kPremultipliedOver,
                            DrawKind::kAdditive, DrawKind::kOther,   DrawKind::kSrcOver};
  for (uint32_t d = 0; d < 6; ++d) ASSERT_EQ(draw_kind(*h.draws.find(d)), kinds[d]) << "draw " << d;
  const uint64_t masks[] = {0x1, 0x3, 0x7, 0xF, 0x6, 0x9, 0x8};
  std::vector<Fragment> frags;
  for (int i = 0; i < 37; ++i)
    frags.push_back(frag(uint32_t(i % 5), uint16_t(i % 4), uint16_t(i / 4 % 2), masks[i % 7], i % 3 ? 0.5f : 1.0f));
  const std::string path = tmp.path("kinds.trace");
  {
    TraceWriter w(path, h);
    for (const Fragment& f : frags) w.write(f);
    w.finish();
  }
  // Expected figures.
  std::map<std::string, std::array<uint64_t, 3>> want;  // kind: draws, fragments, covered samples
  for (int k = 0; k < kDrawKinds; ++k) want[to_string(DrawKind(k))] = {0, 0, 0};
  for (DrawKind k : kinds) ++want[to_string(k)][0];
  uint64_t covered = 0, see_covered = 0, translucent = 0, translucent_covered = 0;
  std::map<int, uint64_t> per_pixel, union_mask;
  for (const Fragment& f : frags) {
    const DrawKind k = kinds[f.draw_id];
    const uint64_t c = uint64_t(__builtin_popcountll(f.coverage));
    ++want[to_string(k)][1];
    want[to_string(k)][2] += c;
    covered += c;
    if (k == DrawKind::kSrcOver || k == DrawKind::kPremultipliedOver) {
      see_covered += c;
      if (f.alpha < 1.0f) {
        ++translucent;
        translucent_covered += c;
      }
      ++per_pixel[f.y * 4 + f.x];
      union_mask[f.y * 4 + f.x] |= f.coverage;
    }
  }
  uint64_t see_frags = 0, see_max = 0, see_samples = 0;
  for (const auto& [px, n] : per_pixel) {
    see_frags += n;
    see_max = std::max(see_max, n);
    see_samples += uint64_t(__builtin_popcountll(union_mask[px]));
  }
  ASSERT_GT(see_max, 1u) << "the test's trace should stack transparent fragments";
  const CliResult r = run_ropsim(tmp, "trace info --json '" + path + "'");
  ASSERT_EQ(r.code, 0) << r.describe();
  const auto j = nlohmann::json::parse(r.out);
  for (const auto& [kind, v] : want) {
    EXPECT_EQ(j["draw_kinds"][kind]["draws"], v[0]) << kind;
    EXPECT_EQ(j["draw_kinds"][kind]["fragments"], v[1]) << kind;
    EXPECT_EQ(j["draw_kinds"][kind]["covered_samples"], v[2]) << kind;
  }
  const auto& t = j["transparent"];
  EXPECT_EQ(t["covered_samples"], see_covered);
  EXPECT_DOUBLE_EQ(t["covered_samples_share"].get<double>(), double(see_covered) / double(covered));
  EXPECT_EQ(t["pixels"], per_pixel.size());
  EXPECT_DOUBLE_EQ(t["fragments_per_pixel"]["mean"].get<double>(), double(see_frags) / double(per_pixel.size()));
  EXPECT_EQ(t["fragments_per_pixel"]["max"], see_max);
  EXPECT_EQ(t["samples"], see_samples);
  EXPECT_DOUBLE_EQ(t["fragments_per_covered_sample"]["mean"].get<double>(), double(see_covered) / double(see_samples));
  EXPECT_DOUBLE_EQ(t["screen_samples_share"].get<double>(), double(see_samples) / (4.0 * 2.0 * 4.0));
  ASSERT_GT(translucent, 0u);
  ASSERT_LT(translucent_covered, see_covered) << "the test's trace should have transparent fragments at alpha 1";
  EXPECT_EQ(t["translucent"]["fragments"], translucent);
  EXPECT_EQ(t["translucent"]["covered_samples"], translucent_covered);
  EXPECT_DOUBLE_EQ(t["translucent"]["covered_samples_share"].get<double>(),
                   double(translucent_covered) / double(covered));
  EXPECT_EQ(j["header"]["draws"].size(), 6u) << "the header's table";
  // The text output: a line per kind and the transparent share.
  const CliResult text = run_ropsim(tmp, "trace info '" + path + "'");
  ASSERT_EQ(text.code, 0) << text.describe();
  const auto& a = want[to_string(DrawKind::kAdditive)];
  EXPECT_NE(text.out.find("    additive            " + std::to_string(a[0]) + " draws, " + std::to_string(a[1]) +
                          " fragments, " + std::to_string(a[2]) + " covered samples"),
            std::string::npos)
      << text.out;
  char share[64];
  std::snprintf(share, sizeof share, "%.2f%% of the covered samples", 100.0 * double(see_covered) / double(covered));
  EXPECT_NE(text.out.find(share), std::string::npos) << text.out;
  // A run's report of the frame carries the same figures, whatever the
  // method and fidelity.
  for (const char* how : {"--method lk", "--method blend --fidelity cycle"}) {
    const CliResult run = run_ropsim(tmp, "run --trace '" + path + "' " + how + " --report -");
    ASSERT_EQ(run.code, 0) << run.describe();
    const auto rj = nlohmann::json::parse(run.out);
    ASSERT_TRUE(rj.contains("frame")) << how << ": " << run.out.substr(0, 400);
    const auto& fr = rj["frame"];
    EXPECT_EQ(fr["covered_samples"], covered) << how;
    EXPECT_DOUBLE_EQ(fr["transparent_share"].get<double>(), double(see_covered) / double(covered)) << how;
    EXPECT_DOUBLE_EQ(fr["translucent_share"].get<double>(), double(translucent_covered) / double(covered)) << how;
    EXPECT_DOUBLE_EQ(fr["transparent_screen_share"].get<double>(), double(see_samples) / 32.0) << how;
    EXPECT_DOUBLE_EQ(fr["transparent_depth_complexity"].get<double>(), double(see_covered) / double(see_samples))
        << how;
    EXPECT_EQ(fr["transparent_fragments_per_pixel_max"], see_max) << how;
  }
  // trace validate names the table.
  const CliResult val = run_ropsim(tmp, "trace validate '" + path + "'");
  EXPECT_EQ(val.out, path + ": valid, 37 fragments, 6 draw states (no checksum)\n") << val.describe();
}

TEST(TraceV2Info, AVersion1TraceIsAllSrcOver) {
  TempDir tmp;
  const TraceHeader h = plain_header(4, 4, 2);
  const std::vector<Fragment> frags = {frag(0, 0, 0, 0x1), frag(3, 0, 0, 0x3), frag(3, 1, 0, 0xF)};
  const std::string path = tmp.path("v1.trace");
  {
    TraceWriter w(path, h);
    for (const Fragment& f : frags) w.write(f);
    w.finish();
  }
  ASSERT_EQ(read_file(path)[8], 1) << "no table: version 1";
  const CliResult r = run_ropsim(tmp, "trace info --json '" + path + "'");
  ASSERT_EQ(r.code, 0) << r.describe();
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["draw_kinds"]["src-over"]["draws"], 4) << "draw ids 0..3";
  EXPECT_EQ(j["draw_kinds"]["src-over"]["fragments"], 3);
  EXPECT_EQ(j["draw_kinds"]["src-over"]["covered_samples"], 7);
  EXPECT_EQ(j["draw_kinds"]["opaque"]["fragments"], 0);
  EXPECT_DOUBLE_EQ(j["transparent"]["covered_samples_share"].get<double>(), 1.0);
  EXPECT_EQ(j["transparent"]["pixels"], 2);
  EXPECT_EQ(j["transparent"]["fragments_per_pixel"]["max"], 2);
  EXPECT_DOUBLE_EQ(j["transparent"]["fragments_per_covered_sample"]["mean"].get<double>(), 7.0 / 6.0);
  EXPECT_EQ(j["header"]["version"], 1);
  EXPECT_EQ(j["header"]["draws"], nlohmann::json::array());
}

}  // namespace
