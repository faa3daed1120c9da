// The digests: every timing figure of the cycle model over configs x methods
// x traces (scripts/timing_digest.sh) and every golden-model output over
// scenes x methods x spp (scripts/golden_digest.sh). A refactor that must not
// change the model leaves them equal to the committed tests/data/*.expected;
// a deliberate model change regenerates them
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

/// Runs scripts/NAME.sh against the built ropsim and compares its lines with
/// tests/data/NAME.expected.
void expect_digest(const std::string& name, const char* what) {
  const std::string cmd = "ROPSIM='" ROPSIM_BINARY "' bash '" ROPSIM_SOURCE_DIR "/scripts/" + name + ".sh' 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr) << "cannot run " << cmd;
  std::string out;
  char buf[4096];
  for (size_t n; (n = fread(buf, 1, sizeof buf, p)) > 0;) out.append(buf, n);
  const int st = pclose(p);
  ASSERT_EQ(st, 0) << name << ".sh failed:\n" << out;
  std::istringstream got_s(out);
  std::ifstream want_s(ROPSIM_SOURCE_DIR "/tests/data/" + name + ".expected");
  ASSERT_TRUE(want_s) << "tests/data/" << name << ".expected is missing";
  const auto got = lines_of(got_s), want = lines_of(want_s);
  ASSERT_EQ(got.size(), want.size()) << "the digest has " << got.size() << " runs, the committed one " << want.size();
  int differ = 0;
  for (size_t i = 0; i < got.size(); ++i)
    if (got[i] != want[i] && ++differ <= 10)
      ADD_FAILURE() << what << " changed:\n  committed: " << want[i] << "\n  now:       " << got[i];
  EXPECT_EQ(differ, 0) << differ << " of " << got.size() << " runs changed";
}

// Every timing figure of the cycle model (config method trace total_cycles digest).
TEST(TimingDigest, MatchesTheCommittedDigest) { expect_digest("timing_digest", "a timing figure"); }

// The golden model's counters, image and error against the reference
// (scene method spp counters png rmse); committed from the model before the
// functional-ROP refactor.
TEST(GoldenDigest, MatchesTheCommittedDigest) { expect_digest("golden_digest", "a golden-model output"); }

}  // namespace
