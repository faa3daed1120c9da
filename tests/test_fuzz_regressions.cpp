// Every input kept in fuzz/regressions/TARGET/ (crashes the fuzzers found, and
// the known trigger inputs of defects since fixed) runs through its fuzz
// target (fuzz/fuzz_targets.h) in the normal build, and under ASan + UBSan in
// the sanitizer build: an input that crashes, aborts or throws anything but an
// input error again fails here.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

#include "fuzz/fuzz_targets.h"
#include "traces/format/trace.h"
#include "traces/raster/sample_patterns.h"

#ifndef ROPSIM_SOURCE_DIR
#error "ROPSIM_SOURCE_DIR must name the source tree (tests/CMakeLists.txt)"
#endif

namespace fs = std::filesystem;

namespace ropsim_fuzz {
/// The test's parameter as the target's name (not its bytes).
void PrintTo(const Target& t, std::ostream* os) { *os << t.name; }
}  // namespace ropsim_fuzz

namespace {

std::vector<fs::path> inputs_of(const std::string& target) {
  std::vector<fs::path> v;
  const fs::path dir = fs::path(ROPSIM_SOURCE_DIR) / "fuzz" / "regressions" / target;
  if (fs::is_directory(dir))
    for (const auto& e : fs::directory_iterator(dir))
      if (e.is_regular_file()) v.push_back(e.path());
  std::sort(v.begin(), v.end());
  return v;
}

class FuzzRegressions : public ::testing::TestWithParam<ropsim_fuzz::Target> {};

TEST_P(FuzzRegressions, EveryKeptInputIsAnInputErrorOrRunsClean) {
  const auto& t = GetParam();
  const auto inputs = inputs_of(t.name);
  ASSERT_FALSE(inputs.empty()) << "fuzz/regressions/" << t.name << "/ holds no input";
  for (const auto& p : inputs) {
    std::ifstream f(p, std::ios::binary);
    const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    SCOPED_TRACE(p.string());
    EXPECT_NO_THROW(t.run(bytes.data(), bytes.size())) << "an exception other than an input error escaped";
  }
}

INSTANTIATE_TEST_SUITE_P(Targets, FuzzRegressions, ::testing::ValuesIn(ropsim_fuzz::targets()),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(FuzzMutators, TraceCountMutationsKeepTheHeaderCheck) {
  // The trace target's mutator rewrites bytes 42..47 and recomputes the
  // header check, so a checked trace's mutated count passes the check and
  // meets the reader's bound on the payload: 2^48 - 1 (seed 1) is refused by
  // the bound, a count of 0 (seed 0) reads as "not recorded".
  using namespace ropsim;
  const std::string path =
      (fs::temp_directory_path() / ("ropsim-mutator-" + std::to_string(::getpid()) + ".trace")).string();
  TraceHeader h;
  h.width = h.height = 8;
  h.spp = 4;
  h.positions = standard_sample_positions(4);
  {
    TraceWriter w(path, h);
    Fragment f;
    f.coverage = 0xF;
    f.z0 = 0.5f;
    for (int i = 0; i < 10; ++i) w.write(f);
    w.finish();
  }
  std::ifstream in(path, std::ios::binary);
  const std::vector<uint8_t> file((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_EQ(file[10], 3) << "a checked, checksummed trace";
  for (uint32_t seed = 0; seed < 60; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    std::vector<uint8_t> m = file;
    ropsim_fuzz::mutate_trace_count(m.data(), m.size(), seed);
    std::FILE* f = std::fopen(path.c_str(), "wb");
    ASSERT_TRUE(f != nullptr);
    std::fwrite(m.data(), 1, m.size(), f);
    std::fclose(f);
    std::string msg;
    try {
      TraceReader r(path);
      if (seed % 6 == 0) {
        EXPECT_FALSE(r.recorded_fragments().has_value());
      }
    } catch (const TraceError& e) {
      msg = e.what();
    }
    EXPECT_EQ(msg.find("header check mismatch"), std::string::npos) << msg;
    if (seed % 6 == 1) {
      EXPECT_NE(msg.find("fragment count (bytes 42..47) 281474976710654"), std::string::npos) << msg;
    }
  }
  fs::remove(path);
}

TEST(FuzzMutators, TraceDrawMutationsKeepTheHeaderCheckAndReachTheFieldChecks) {
  // The draw-record mutator (version 2) sets one field of one record and
  // recomputes the header check over the table: no mutation stops at the
  // check, and some reach DrawTable::validate()'s or the reader's field checks.
  using namespace ropsim;
  const std::string seed_file =
      std::string(ROPSIM_SOURCE_DIR) + "/fuzz/regressions/trace/v2-testcard-8x8-zstd-checksummed.rtrace";
  std::ifstream in(seed_file, std::ios::binary);
  const std::vector<uint8_t> file((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GT(file.size(), 48u) << seed_file;
  ASSERT_EQ(file[8], 2) << "a version 2 seed";
  const std::string path =
      (fs::temp_directory_path() / ("ropsim-draw-mutator-" + std::to_string(::getpid()) + ".trace")).string();
  int field_errors = 0, changed = 0;
  for (uint32_t seed = 0; seed < 400; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    std::vector<uint8_t> m = file;
    ropsim_fuzz::mutate_trace_draws(m.data(), m.size(), seed);
    changed += m != file;
    std::FILE* f = std::fopen(path.c_str(), "wb");
    ASSERT_TRUE(f != nullptr);
    std::fwrite(m.data(), 1, m.size(), f);
    std::fclose(f);
    std::string msg;
    try {
      TraceReader r(path);
      Fragment frag;
      while (r.next(frag)) {
      }
    } catch (const TraceError& e) {
      msg = e.what();
    }
    EXPECT_EQ(msg.find("header check mismatch"), std::string::npos) << msg;
    field_errors += msg.find(": draw state ") != std::string::npos;
  }
  EXPECT_GT(changed, 200) << "the mutator changed too few inputs";
  EXPECT_GT(field_errors, 50) << "too few mutations reached the draw records' checks";
  fs::remove(path);
}

}  // namespace
