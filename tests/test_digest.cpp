// The timing digest (scripts/timing_digest.sh): every timing figure of the
// cycle model over configs x methods x traces, digested per run. A refactor
// that must not change the model leaves it equal to the committed
// tests/data/timing_digest.expected; a deliberate model change regenerates it
// (ROPSIM=build/ropsim scripts/timing_digest.sh > tests/data/timing_digest.expected)
// and says why in its commit.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#ifndef ROPSIM_BINARY
#error "ROPSIM_BINARY must name the built ropsim executable (tests/CMakeLists.txt)"
#endif

namespace {

std::vector<std::string> lines_of(std::istream& in) {
  std::vector<std::string> v;
  for (std::string l; std::getline(in, l);)
    if (!l.empty()) v.push_back(l);
  return v;
}

TEST(TimingDigest, MatchesTheCommittedDigest) {
  const std::string cmd = "ROPSIM='" ROPSIM_BINARY "' bash '" ROPSIM_SOURCE_DIR "/scripts/timing_digest.sh' 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr) << "cannot run " << cmd;
  std::string out;
  char buf[4096];
  for (size_t n; (n = fread(buf, 1, sizeof buf, p)) > 0;) out.append(buf, n);
  const int st = pclose(p);
  ASSERT_EQ(st, 0) << "timing_digest.sh failed:\n" << out;
  std::istringstream got_s(out);
  std::ifstream want_s(ROPSIM_SOURCE_DIR "/tests/data/timing_digest.expected");
  ASSERT_TRUE(want_s) << "tests/data/timing_digest.expected is missing";
  const auto got = lines_of(got_s), want = lines_of(want_s);
  ASSERT_EQ(got.size(), want.size()) << "the digest has " << got.size() << " runs, the committed one " << want.size();
  int differ = 0;
  for (size_t i = 0; i < got.size(); ++i)
    if (got[i] != want[i] && ++differ <= 10)
      ADD_FAILURE() << "a timing figure changed (config method trace total_cycles digest):\n  committed: " << want[i]
                    << "\n  now:       " << got[i];
  EXPECT_EQ(differ, 0) << differ << " of " << got.size() << " runs changed their timing";
}

}  // namespace
