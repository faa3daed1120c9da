#include "fuzz/fuzz_targets.h"

#include <unistd.h>
#include <xxhash.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <cstdlib>
#include <stdexcept>
#include <vector>

#include "util/errors.h"
#include "rtl_models/golden/golden_model.h"
#include "rtl_models/config/hw_config.h"
#include "sim/fidelity/sampled/livepoint_file.h"
#include "rtl_models/algo/numerics.h"
#include "traces/capture/scene_file.h"
#include "sim/study/study.h"
#include "traces/format/trace.h"

namespace ropsim_fuzz {

namespace {

/// The screen whose resolved rows are also read back (every pixel, so a
/// larger screen would only cost time): any screen is modelled and resolved,
/// since the state, image and directory follow what the trace touches.
constexpr uint64_t kMaxRowsPixels = uint64_t{1} << 20;
/// Fragments read from one input (a fuzzed header may promise billions).
constexpr uint64_t kMaxFuzzFragments = 1u << 16;
/// Fragments of a trace the oracle writes and reads back (check_accepted_trace).
constexpr uint64_t kMaxRoundTripFragments = 1u << 12;
/// Studies expanded in full (a fuzzed study may ask for 100,000 points).
constexpr uint64_t kMaxFuzzStudyPoints = 4096;

/// Runs fn; an input error (std::runtime_error) is an expected outcome.
template <class F>
int expect_input_errors(F&& fn) {
  try {
    fn();
  } catch (const std::runtime_error&) {
  }
  return 0;
}

}  // namespace

std::string input_file(const uint8_t* data, size_t size, const char* suffix) {
  const char* tmp = std::getenv("TMPDIR");
  const std::string path =
      std::string(tmp && *tmp ? tmp : "/tmp") + "/ropsim-fuzz-" + std::to_string(::getpid()) + suffix;
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f || (size && std::fwrite(data, 1, size, f) != size) || std::fclose(f) != 0) std::abort();
  return path;
}

/// The trace target's oracle for what the reader accepts: a header whose
/// draw table is valid, fragments of the table's draws, and a trace that the
/// writer takes as it is and that reads back with the same header. Aborts
/// otherwise.
void check_accepted_trace(const std::string& path, const ropsim::TraceHeader& h,
                          const std::vector<ropsim::Fragment>& frags) {
  auto fail = [](const std::string& why) {
    std::fprintf(stderr, "the trace reader accepted %s\n", why.c_str());
    std::abort();
  };
  if (const std::string why = ropsim::validate_header(h); !why.empty()) fail("an invalid header: " + why);
  if (h.version() == ropsim::kTraceVersion && !h.draws.empty()) fail("draw states in a version 1 header");
  for (const ropsim::Fragment& f : frags)
    if (!h.draws.empty() && !h.draws.find(f.draw_id))
      fail("a fragment of draw " + std::to_string(f.draw_id) + ", which the table lacks");
  const std::string again = path + ".again.rtrace";
  try {
    {
      ropsim::TraceWriter w(again, h);
      for (const ropsim::Fragment& f : frags) w.write(f);
      w.finish();
    }
    ropsim::TraceReader r(again);
    if (ropsim::header_to_json(r.header()) != ropsim::header_to_json(h) || !(r.header().draws == h.draws))
      fail("a header that does not read back the same:\n" + ropsim::header_to_json(h) + "\n" +
           ropsim::header_to_json(r.header()));
    ropsim::Fragment f;
    size_t n = 0;
    while (r.next(f)) ++n;
    if (n != frags.size()) fail("fragments that do not read back");
  } catch (const std::runtime_error& e) {
    fail(std::string("a trace that does not write and read back: ") + e.what());
  }
  std::remove(again.c_str());
}

int fuzz_trace(const uint8_t* data, size_t size) {
  const std::string path = input_file(data, size, ".rtrace");
  return expect_input_errors([&] {
    ropsim::TraceReader r(path);
    const ropsim::TraceHeader& h = r.header();
    ropsim::GoldenConfig cfg;
    cfg.method = ropsim::Method::kLk;
    ropsim::StochasticModel model(h, cfg);
    ropsim::Fragment f;
    std::vector<ropsim::Fragment> frags;
    bool complete = false;
    for (uint64_t n = 0; n < kMaxFuzzFragments; ++n) {
      if (!r.next(f)) {
        complete = true;
        break;
      }
      model.draw(f);
      if (frags.size() < kMaxRoundTripFragments) frags.push_back(f);
    }
    // A trace read to its end, whole: the oracle (on the fragments it kept).
    if (complete && r.records_read() <= kMaxRoundTripFragments) check_accepted_trace(path, h, frags);
    const ropsim::Image img = model.resolve();
    if (img.width != h.width || img.height != h.height) std::abort();
    if (img.tiles() > model.store().tiles()) std::abort();  // the image holds only touched tiles
    if (uint64_t(h.width) * h.height <= kMaxRowsPixels) {
      std::vector<float> row(size_t(h.width) * 3);
      for (uint32_t y = 0; y < h.height; ++y) img.row(y, row.data());
    }
  });
}

int fuzz_scene(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  return expect_input_errors([&] { (void)ropsim::parse_scene_text(text, "fuzz-scene.toml"); });
}

int fuzz_design(const uint8_t* data, size_t size) {
  std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<std::string> overrides;
  if (const auto sep = text.find("\n%%\n"); sep != std::string::npos) {
    std::string rest = text.substr(sep + 4);
    text.resize(sep + 1);
    for (size_t a = 0; a <= rest.size();) {
      const size_t b = std::min(rest.find('\n', a), rest.size());
      if (b > a) overrides.push_back(rest.substr(a, b - a));
      a = b + 1;
    }
  }
  ropsim::HwConfig cfg;
  bool loaded = false;
  expect_input_errors([&] {
    cfg = ropsim::parse_hw_config(text, "fuzz-design.toml", overrides);  // resolve_hw_config, from memory
    loaded = true;
  });
  if (!loaded) return 0;
  // Printed and read back, the design is the same design.
  const std::string printed = ropsim::hw_config_to_toml(cfg);
  ropsim::HwConfig again;
  try {
    again = ropsim::parse_hw_config(printed, "printed.toml");
  } catch (const std::runtime_error& e) {
    std::fprintf(stderr, "a loaded design, printed, does not load: %s\n%s", e.what(), printed.c_str());
    std::abort();
  }
  if (ropsim::hw_config_digest(again) != ropsim::hw_config_digest(cfg) || ropsim::hw_config_to_toml(again) != printed) {
    std::fprintf(stderr, "a design printed and read back differs:\n%s---\n%s", printed.c_str(),
                 ropsim::hw_config_to_toml(again).c_str());
    std::abort();
  }
  return 0;
}

int fuzz_study(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  return expect_input_errors([&] {
    // Named in the current folder: the files it names are looked for there.
    const ropsim::Study s = ropsim::parse_study(text, "fuzz-study.toml");
    // Expanding 100,000 points runs the code 10,000 do, for 100 ms an input:
    // the large ones are checked for their count only, so the campaign
    // reaches its executions (docs/testing.md "Fuzzing").
    if (s.points_at_most <= kMaxFuzzStudyPoints) (void)ropsim::expand_study(s);
  });
}

namespace {

/// The oracle of the livepoints target: the first field of a library that
/// read but lies outside the ranges docs/livepoints.md gives, or "". Written
/// from the document, apart from the reader's own checks.
std::string library_out_of_range(const ropsim::LivePoints& lib) {
  using namespace ropsim;
  const InputSpec& in = lib.input.spec;
  const TraceHeader& h = lib.header;
  const SamplingParams& s = lib.params;
  const MethodConfig& m = lib.method;
  const uint64_t n = lib.fragments;
  if (in.repeat < 1 || in.repeat > 1000) return "repeat " + std::to_string(in.repeat);
  if (!validate_header(h).empty()) return "the trace header: " + validate_header(h);
  if (m.slab_layers < 1 || m.slab_layers > 16) return "SLAB k " + std::to_string(m.slab_layers);
  if (m.slab_bits < 1 || m.slab_bits > 64) return "SLAB b " + std::to_string(m.slab_bits);
  if (n >= (uint64_t{1} << 48) * in.repeat) return "N " + std::to_string(n);
  if (s.units != lib.points.size() || s.units < 1) return "K " + std::to_string(s.units);
  if (lib.whole ? s.unit_fragments != n : (s.unit_fragments < 1 || s.unit_fragments > n / s.units))
    return "U " + std::to_string(s.unit_fragments);
  if (lib.counters.fragments != n) return "the fragments counter";
  bool counters_ok = true;
  lib.counters.for_each([&](const char*, uint64_t v) {
    if (v / (16 * 64 + 289) > n) counters_ok = false;
  });
  if (!counters_ok) return "a counter over N (16 x 64 + 289)";
  uint64_t end = 0;
  for (const LivePoint& p : lib.points) {
    if (p.window != s.unit_fragments || p.first < end || p.warmup + p.window > p.fragments.size() ||
        p.first + p.fragments.size() > n)
      return "a live-point's fragments";
    end = p.first + p.fragments.size();
    if (p.warming.size() > s.warming_fragments || p.warming.size() > p.first) return "a live-point's touches";
    for (float z : p.pre.depth)
      if (!(z >= 0.0f && z <= 1.0f)) return "a pre-state depth";
    for (const SlabPixel& sp : p.pre.slabs)
      if (sp.count > m.slab_layers) return "a slab pixel's layers";
    if (p.tiles.size() > p.resident.size()) return "a live-point's tile pixels";
    for (float z : p.tiles.depth)
      if (!(z >= 0.0f && z <= 1.0f)) return "a tile pixel's depth";
  }
  if (end != n) return "the last live-point does not end the input";
  if (uint64_t(h.width) * h.height <= kMaxRowsPixels) {
    std::vector<float> row(size_t(h.width) * 3);
    for (uint32_t y = 0; y < h.height; ++y) {
      lib.image.row(y, row.data());
      for (float c : row)
        if (!(c >= 0.0f) || (std::isinf(c) && h.color_format == ColorFormat::kRgbUnorm8 &&
                              !std::isinf(lib.image.background()[0]) && !std::isinf(lib.image.background()[1]) &&
                              !std::isinf(lib.image.background()[2])))
          return "image row " + std::to_string(y) + " holds " + std::to_string(c);
    }
  }
  return "";
}

uint64_t get_le(const uint8_t* p, int n) {
  uint64_t v = 0;
  for (int i = 0; i < n; ++i) v |= uint64_t(p[i]) << (8 * i);
  return v;
}

}  // namespace

size_t trace_header_bytes(const uint8_t* data, size_t size) {
  if (size < 48 || std::memcmp(data, ropsim::kTraceMagic, 8) != 0) return 0;
  size_t head = 48 + 2 * size_t(data[20]) + size_t(get_le(data + 40, 2));
  if (get_le(data + 8, 2) != ropsim::kTraceVersionDraws) return head;
  if (size < head + 4) return 0;
  const uint64_t n = get_le(data + head, 4);
  head += 4;
  for (uint64_t i = 0; i < n; ++i) {
    if (size < head + ropsim::kDrawRecordFixedBytes) return 0;
    head += ropsim::kDrawRecordFixedBytes + data[head + ropsim::kDrawRecordFixedBytes - 1];
  }
  return head <= size ? head : 0;
}

void fix_trace_header_check(uint8_t* data, size_t size) {
  if (size < 48 || std::memcmp(data, ropsim::kTraceMagic, 8) != 0 || !(get_le(data + 10, 2) & ropsim::kTraceFlagHeaderCheck))
    return;
  const size_t head = trace_header_bytes(data, size);
  if (head == 0 || size < head + ropsim::kHeaderCheckBytes) return;
  const uint64_t c = XXH3_64bits(data, head);
  for (int i = 0; i < 8; ++i) data[head + size_t(i)] = uint8_t(c >> (8 * i));
}

void mutate_trace_count(uint8_t* data, size_t size, uint32_t seed) {
  if (size < 48) return;
  const uint64_t field = get_le(data + 42, 6), mask48 = (uint64_t{1} << 48) - 1;
  uint64_t v = field;
  switch (seed % 6) {
    case 0: v = 0; break;                                          // not recorded
    case 1: v = mask48; break;                                     // 2^48 - 1 fragments + 1
    case 2: v = field ^ (uint64_t{1} << (seed / 6 % 48)); break;  // one bit flipped
    case 3: v = field + 1 + seed / 6 % 3; break;                   // a few more
    case 4: v = field > 1 ? field - 1 : field + 1; break;          // one fewer
    default: v = (uint64_t(seed) * 0x9E3779B97F4A7C15ull) & mask48; break;
  }
  for (int i = 0; i < 6; ++i) data[42 + i] = uint8_t((v & mask48) >> (8 * i));
  fix_trace_header_check(data, size);
}

void mutate_trace_draws(uint8_t* data, size_t size, uint32_t seed) {
  if (trace_header_bytes(data, size) == 0 || get_le(data + 8, 2) != ropsim::kTraceVersionDraws) return;
  const size_t table = 48 + 2 * size_t(data[20]) + size_t(get_le(data + 40, 2));
  const uint64_t n = get_le(data + table, 4);
  if (n == 0) return;
  size_t at = table + 4;  // the record seed picks
  for (uint64_t i = 0, pick = seed % n; i < pick; ++i) at += ropsim::kDrawRecordFixedBytes + data[at + ropsim::kDrawRecordFixedBytes - 1];
  seed /= uint32_t(n);
  // A field (record offset, bytes) and a value for it: the valid range's
  // ends, one past them, and the byte's ends.
  static const struct {
    size_t offset, bytes;
    uint32_t last;  ///< the field's largest valid value
  } fields[] = {{0, 4, 0xFFFFFFFFu}, {4, 1, 7}, {5, 1, 4}, {6, 1, 4}, {7, 1, 14}, {8, 1, 14}, {9, 1, 14},
                {10, 1, 14},         {11, 1, 7}, {12, 1, 15}, {13, 1, 2}, {14, 4, 0}, {26, 4, 0}};
  const auto& fl = fields[seed % (sizeof fields / sizeof fields[0])];
  seed /= uint32_t(sizeof fields / sizeof fields[0]);
  uint32_t v;
  if (fl.offset >= 14) {  // a blend colour channel: NaN, infinity, -0, a large finite value
    const uint32_t pats[] = {0x7FC00000u, 0x7F800000u, 0x80000000u, 0x7F7FFFFFu, 0x3F800000u};
    v = pats[seed % 5];
  } else if (fl.offset == 0) {  // a draw id: the next record's, the previous one's, one more, 0
    const uint32_t id = uint32_t(get_le(data + at, 4));
    const uint32_t ids[] = {id + 1, id - 1, 0, 0xFFFFFFFFu};
    v = ids[seed % 4];
  } else {
    const uint32_t vals[] = {0, fl.last, fl.last + 1, 0xFF};
    v = vals[seed % 4];
  }
  for (size_t i = 0; i < fl.bytes; ++i) data[at + fl.offset + i] = uint8_t(v >> (8 * i));
  fix_trace_header_check(data, size);
}

int fuzz_livepoints(const uint8_t* data, size_t size) {
  std::vector<uint8_t> file;
  if (size >= 8 && std::memcmp(data, "ROPSIMLP", 8) == 0) {
    file.assign(data, data + size);
  } else {
    file = ropsim::wrap_livepoint_payload(data, size);
  }
  const std::string path = input_file(file.data(), file.size(), ".rlp");
  return expect_input_errors([&] {
    const ropsim::LivePoints lib = ropsim::read_livepoints(path);
    // What reads has every field in range.
    if (const std::string why = library_out_of_range(lib); !why.empty()) {
      std::fprintf(stderr, "a library with a field out of range was accepted: %s\n", why.c_str());
      std::abort();
    }
    // What reads, writes and reads back to the same bytes.
    const std::string again = path + ".again.rlp", third = path + ".third.rlp";
    ropsim::write_livepoints(again, lib);
    ropsim::write_livepoints(third, ropsim::read_livepoints(again));
    auto bytes = [](const std::string& p) {
      std::ifstream f(p, std::ios::binary);
      return std::vector<char>((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    };
    const bool same = bytes(again) == bytes(third);
    std::remove(again.c_str());
    std::remove(third.c_str());
    if (!same) std::abort();
  });
}

}  // namespace ropsim_fuzz
