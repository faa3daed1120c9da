// Every input kept in fuzz/regressions/TARGET/ (crashes the fuzzers found, and
// the known trigger inputs of defects since fixed) runs through its fuzz
// target (fuzz/fuzz_targets.h) in the normal build, and under ASan + UBSan in
// the sanitizer build: an input that crashes, aborts or throws anything but an
// input error again fails here.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

#include "fuzz_targets.h"

#ifndef ROPSIM_SOURCE_DIR
#error "ROPSIM_SOURCE_DIR must name the source tree (tests/CMakeLists.txt)"
#endif

namespace fs = std::filesystem;

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

}  // namespace
