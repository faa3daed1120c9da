// The README's commands run as written. The "Using it" block is executed in
// order, verbatim, from a folder laid out like the checkout (its top-level
// entries linked, build/ the tested build), so each command finds the files
// the ones before it wrote; the quick start's scripts and every script of
// the "Developing" table are run by CI or guarded by a named test.
#include <gtest/gtest.h>

#include <filesystem>
#include <regex>
#include <string>
#include <vector>

#include "tests/study_test_util.h"

namespace {

using namespace ropsim_test;
namespace fs = std::filesystem;

const fs::path kSource = ROPSIM_SOURCE_DIR;

/// The body of the first ```sh block after the heading `heading`.
std::string sh_block_after(const std::string& text, const std::string& heading) {
  const size_t h = text.find("\n" + heading + "\n");
  if (h == std::string::npos) return "";
  const size_t a = text.find("```sh\n", h);
  if (a == std::string::npos) return "";
  const size_t b = text.find("```", a + 6);
  return b == std::string::npos ? "" : text.substr(a + 6, b - a - 6);
}

TEST(Readme, UsingItRunsAsWrittenInOrder) {
  const std::string readme = slurp(kSource / "README.md");
  const std::string block = sh_block_after(readme, "## Using it");
  ASSERT_FALSE(block.empty()) << "README.md has no ```sh block under '## Using it'";
  if (!std::getenv("ROPSIM_MESH_DIR") && !fs::exists(kSource / ".." / "shared" / "data" / "meshes"))
    GTEST_SKIP() << "the shared meshes are absent: the README captures the motor";
  Scratch scratch("ropsim-test-readme");
  // The checkout's layout: every top-level entry linked (outputs land in the
  // scratch folder, not in the source tree), build/ the build under test,
  // and ../shared beside it, as beside the checkout.
  const fs::path co = scratch.dir / "checkout";
  fs::create_directories(co);
  if (fs::exists(kSource / ".." / "shared"))
    fs::create_directory_symlink(kSource / ".." / "shared", scratch.dir / "shared");
  for (const auto& e : fs::directory_iterator(kSource)) {
    const std::string name = e.path().filename().string();
    if (name == "build" || name == "out" || name.rfind("build-", 0) == 0 || name[0] == '.') continue;
    fs::create_symlink(e.path(), co / name);
  }
  fs::create_directory_symlink(fs::path(ROPSIM_BINARY).parent_path(), co / "build");
  // Verbatim, stopping at the first failure, which it names.
  std::ofstream(co / "readme.sh") << "set -euo pipefail\n"
                                     "trap 'echo \"README command failed (status $?): $BASH_COMMAND\" >&2' ERR\n"
                                  << block;
  const Ran r = shell(co, "bash readme.sh", 1200);
  EXPECT_EQ(r.status, 0) << "a README command failed:\n" << r.err.substr(r.err.size() > 4000 ? r.err.size() - 4000 : 0);
  // What the commands say they write is there.
  for (const char* f : {"cloth.trace", "motor.trace", "lk.exr", "lk.png", "reference.exr", "alpha_ref.csv", "w.vcd",
                        "phases.csv", "motor.rlp", "st.csv", "motor.log"})
    EXPECT_TRUE(fs::exists(co / f)) << "the README's commands did not write " << f;
  EXPECT_NE(slurp(co / "motor.log").find("functional: 100.0 %"), std::string::npos)
      << "--progress into a log: " << slurp(co / "motor.log");
}

TEST(Readme, QuickStartAndDevelopingScriptsAreRunByCiOrATest) {
  const std::string readme = slurp(kSource / "README.md");
  const std::string ci = slurp(kSource / ".ci" / "run");
  const std::string quick = sh_block_after(readme, "## Quick start");
  ASSERT_FALSE(quick.empty());
  for (const char* script : {"scripts/demo.sh", "scripts/test.sh"}) {
    EXPECT_NE(quick.find(script), std::string::npos) << "the quick start lost " << script;
    EXPECT_NE(ci.find(std::string("bash ") + script), std::string::npos)
        << ".ci/run does not run the quick start's " << script << " on its fresh checkout";
  }
  // The Developing table: | `scripts/X.sh ...` | what | run by |.
  const size_t d = readme.find("\n## Developing\n");
  ASSERT_NE(d, std::string::npos) << "README.md has no '## Developing' section";
  const std::string dev = readme.substr(d, readme.find("\n## ", d + 5) - d);
  std::string tests;
  for (const auto& e : fs::directory_iterator(kSource / "tests"))
    if (e.path().extension() == ".cpp") tests += slurp(e.path());
  const std::regex row(R"(\| `(scripts/[a-z_]+\.sh)[^`]*` \|[^|]*\| ([^|]*) \|)");
  int rows = 0;
  for (std::sregex_iterator it(dev.begin(), dev.end(), row), end; it != end; ++it, ++rows) {
    const std::string script = (*it)[1], by = (*it)[2];
    EXPECT_TRUE(fs::exists(kSource / script)) << "README names " << script << ", which does not exist";
    std::smatch m;
    if (by.find(".ci/run") != std::string::npos) {
      EXPECT_NE(ci.find(script), std::string::npos) << script << ": README says CI runs it; .ci/run does not";
    } else if (std::regex_search(by, m, std::regex(R"(ctest `([A-Za-z]+)\.)"))) {
      EXPECT_NE(tests.find("TEST(" + m[1].str() + ","), std::string::npos)
          << script << ": README names the test suite " << m[1] << ", which does not exist";
    } else {
      EXPECT_NE(by.find("by hand"), std::string::npos) << script << ": 'run by' must be CI, a ctest or by hand";
    }
  }
  EXPECT_GE(rows, 8) << "the Developing table lost rows";
}

}  // namespace
