// `ropsim study run --executor slurm` (docs/studies.md, "On a cluster") on a
// real single-node SLURM cluster that the test starts (scripts/slurm_local.sh:
// munged, slurmctld and slurmd as root, every file in a temporary folder) and
// stops after: the database holds every point once with the results of a local
// run, and a second submission after a point was lost submits only that point.
// Every wait is bounded; a cluster that does not start fails the test with the
// daemons' logs.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "study_test_util.h"

#ifndef ROPSIM_SOURCE_DIR
#error "ROPSIM_SOURCE_DIR must name the source tree (tests/CMakeLists.txt)"
#endif

namespace fs = std::filesystem;

namespace {

using namespace ropsim_test;

/// A study folder's results (study export) without the host's measurements.
Rows model_results(const fs::path& dir, const std::string& study_dir) {
  return ropsim_test::model_results(export_rows(dir, study_dir));
}

const char* kStudy = R"(
[study]
name = "tiny"

[inputs]
scenes = ["eight-layers"]

[axes]
method = ["lk", "enderton"]
spp = [4, 8]
width = 32
height = 32

[slurm]
time = "00:10:00"
throttle = 2
)";

/// The cluster, shared by the tests of the suite: started once, always stopped.
class SlurmStudy : public ::testing::Test {
 protected:
  static fs::path root_;    ///< scratch folder: the cluster in cluster/, the studies beside
  static bool up_;          ///< the cluster started
  static std::string why_;  ///< else: the script's output (with the daemons' logs)

  static fs::path cluster() { return root_ / "cluster"; }

  static void SetUpTestSuite() {
    root_ = fs::temp_directory_path() / ("ropsim-test-slurm-" + std::to_string(::getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_);
    // Bounded: installing the packages on a fresh machine, then the node idle.
    const Ran r =
        shell(root_, "bash '" ROPSIM_SOURCE_DIR "/scripts/slurm_local.sh' start '" + cluster().string() + "'", 480);
    up_ = r.status == 0;
    why_ = "exit status " + std::to_string(r.status) + "\n" + r.out + r.err;
    if (up_) ::setenv("SLURM_CONF", (cluster() / "slurm.conf").c_str(), 1);
  }

  static void TearDownTestSuite() {
    shell(root_, "bash '" ROPSIM_SOURCE_DIR "/scripts/slurm_local.sh' stop '" + cluster().string() + "'", 60);
    ::unsetenv("SLURM_CONF");
    fs::remove_all(root_);
  }

  /// The daemons' logs and the tasks' logs of a study folder, for a message.
  static std::string logs(const std::string& study_dir) {
    std::string s;
    for (const char* f : {"slurmctld.log", "slurmd.log", "munged.log"}) {
      std::string t = slurp(cluster() / f);
      if (t.size() > 4000) t = t.substr(t.size() - 4000);
      s += std::string("===== ") + f + "\n" + t;
    }
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(root_ / study_dir / "slurm", ec))
      s += "===== " + e.path().filename().string() + "\n" + slurp(e.path());
    return s;
  }
};
fs::path SlurmStudy::root_;
bool SlurmStudy::up_ = false;
std::string SlurmStudy::why_;

size_t lines(const std::string& s) {
  size_t n = 0;
  std::istringstream in(s);
  for (std::string l; std::getline(in, l);) n += !l.empty();
  return n;
}

}  // namespace

TEST(StudySlurmFile, ABadSlurmSectionIsRefusedBeforeAnythingIsSubmitted) {
  const fs::path dir = fs::temp_directory_path() / ("ropsim-test-slurm-file-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string head = "[inputs]\nscenes = [\"cloth\"]\n[slurm]\n";
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"queue = \"x\"\n", "slurm.queue"}, {"throttle = 0\n", "slurm.throttle"},   {"time = \"soon\"\n", "slurm.time"},
      {"mem = \"lots\"\n", "slurm.mem"},  {"partition = 3\n", "slurm.partition"}, {"args = [\"qos\"]\n", "slurm.args"},
  };
  for (const auto& [text, key] : bad) {
    std::ofstream(dir / "bad.toml") << head << text;
    const Ran r = ropsim(dir, "study run bad.toml --out st --executor slurm");
    EXPECT_EQ(r.status, 1) << text;
    EXPECT_NE(r.err.find("ropsim: error: bad.toml: " + key + ": "), std::string::npos) << text << "\n" << r.err;
    EXPECT_EQ(lines(r.err), 1u) << r.err;
    EXPECT_FALSE(fs::exists(dir / "st")) << "something ran for:\n" << text;
  }
  fs::remove_all(dir);
}

TEST_F(SlurmStudy, ARunOnTheClusterEqualsALocalRunAndASecondSubmitsOnlyWhatIsMissing) {
  ASSERT_TRUE(up_) << "the SLURM cluster did not start (scripts/slurm_local.sh):\n" << why_;
  std::ofstream(root_ / "tiny.toml") << kStudy;
  const Ran local = ropsim(root_, "study run tiny.toml --out local -j 2 --quiet");
  ASSERT_EQ(local.status, 0) << local.err << local.out;

  const Ran a = ropsim(root_, "study run tiny.toml --out onslurm --executor slurm --wait");
  ASSERT_EQ(a.status, 0) << a.out << a.err << logs("onslurm");
  EXPECT_NE(a.out.find("submitted 0 captures, 2 references, 4 points"), std::string::npos) << a.out;
  EXPECT_NE(a.out.find(": references\n"), std::string::npos) << a.out;
  EXPECT_NE(a.out.find(": points\n"), std::string::npos) << a.out;
  EXPECT_NE(a.out.find("4 points: 4 done, 0 failed, 0 not run yet"), std::string::npos) << a.out;
  // The job scripts: one array per phase, the absolute paths, the [slurm] options.
  const std::string script = slurp(root_ / "onslurm" / "slurm" / "points.sbatch");
  EXPECT_NE(script.find("#SBATCH --array=0-3%2"), std::string::npos) << script;
  EXPECT_NE(script.find("#SBATCH --time=00:10:00"), std::string::npos) << script;
  EXPECT_NE(script.find("'" ROPSIM_BINARY "' study task '" + (root_ / "tiny.toml").string() + "' --out '" +
                        (root_ / "onslurm").string() + "' --kind p"),
            std::string::npos)
      << script;
  EXPECT_EQ(lines(slurp(root_ / "onslurm" / "slurm" / "points.txt")), 4u);

  const Rows want = model_results(root_, "local");
  ASSERT_EQ(want.size(), 4u);
  Rows got = model_results(root_, "onslurm");
  EXPECT_EQ(got, want) << "the cluster changed a result, or a point is missing or twice";
  for (const auto& r : got) EXPECT_EQ(r.at("status"), "ok") << r.at("point") << ": " << r.at("error");

  // Lose one point (its folder and its row): a second submission runs only it.
  const std::string lost = want.at(2).at("point");
  fs::remove_all(root_ / "onslurm" / "points" / lost);
  const Ran del = shell(root_,
                        "/usr/bin/python3 -c \"import sqlite3; d = sqlite3.connect('onslurm/results.db'); "
                        "d.execute('DELETE FROM results WHERE point = ?', ('" +
                            lost + "',)); d.commit()\"",
                        60);
  ASSERT_EQ(del.status, 0) << del.err;
  ASSERT_EQ(model_results(root_, "onslurm").size(), 3u);
  const Ran b = ropsim(root_, "study run tiny.toml --out onslurm --executor slurm --wait --slurm-throttle 1");
  ASSERT_EQ(b.status, 0) << b.out << b.err << logs("onslurm");
  EXPECT_NE(b.out.find("3 already done, 0 failed; submitted 0 captures, 0 references, 1 points"), std::string::npos)
      << b.out;
  EXPECT_EQ(lines(slurp(root_ / "onslurm" / "slurm" / "points.txt")), 1u);
  EXPECT_EQ(lines(slurp(root_ / "onslurm" / "slurm" / "jobs.txt")), 1u);
  EXPECT_NE(slurp(root_ / "onslurm" / "slurm" / "points.sbatch").find("#SBATCH --array=0-0%1"), std::string::npos);
  EXPECT_EQ(model_results(root_, "onslurm"), want);

  // Nothing missing: nothing submitted.
  const Ran c = ropsim(root_, "study run tiny.toml --out onslurm --executor slurm");
  EXPECT_EQ(c.status, 0) << c.out << c.err;
  EXPECT_NE(c.out.find("4 already done, 0 failed; submitted 0 captures, 0 references, 0 points"), std::string::npos)
      << c.out;
}
