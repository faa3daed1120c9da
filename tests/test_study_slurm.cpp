// `ropsim study run --executor slurm` (docs/studies.md, "On a cluster") on a
// real single-node SLURM cluster that each test starts (scripts/slurm_local.sh:
// munged, slurmctld and slurmd as root, every file in a temporary folder) and
// stops after: the database holds every point once with the results of a local
// run, and a second submission after a point was lost submits only that point;
// mesh inputs are captured by a first job array that the references and the
// points follow (afterok), with a memory request; a request larger than the
// node is refused; a point that fails on the cluster records its error while
// the others complete; stopping the cluster (or the death of the test that
// started it) leaves no process of it running. Every wait is bounded; a
// cluster that does not start fails the test with the daemons' logs.
#include <gtest/gtest.h>
#include <signal.h>
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

#include "tests/study_test_util.h"

#ifndef ROPSIM_SOURCE_DIR
#error "ROPSIM_SOURCE_DIR must name the source tree (tests/CMakeLists.txt)"
#endif

namespace fs = std::filesystem;

namespace {

using namespace ropsim_test;

/// A command on the cluster: bounded, so that a broken cluster fails the test
/// (with the logs) instead of hanging it.
constexpr int kClusterTimeout = 90;

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

/// scripts/slurm_local.sh start DIR, owned by this process (stopped when it dies).
std::string start_command(const fs::path& dir) {
  return "env SLURM_LOCAL_OWNER=" + std::to_string(::getpid()) +
         " bash '" ROPSIM_SOURCE_DIR "/scripts/slurm_local.sh' start '" + dir.string() + "'";
}
std::string stop_command(const fs::path& dir) {
  return "bash '" ROPSIM_SOURCE_DIR "/scripts/slurm_local.sh' stop '" + dir.string() + "'";
}

/// The cluster, shared by the tests of the suite (ctest runs each test in its
/// own process, so each gets its own): started once, always stopped.
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
    // SLURM_LOCAL_OWNER: the cluster is stopped if this process dies first.
    const Ran r = shell(root_, start_command(cluster()), 480);
    up_ = r.status == 0;
    why_ = "exit status " + std::to_string(r.status) + "\n" + r.out + r.err;
    if (up_) ::setenv("SLURM_CONF", (cluster() / "slurm.conf").c_str(), 1);
  }

  static void TearDownTestSuite() {
    shell(root_, stop_command(cluster()), 60);
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

  const Ran a = ropsim(root_, "study run tiny.toml --out onslurm --executor slurm --wait", kClusterTimeout);
  ASSERT_EQ(a.status, 0) << a.out << a.err << logs("onslurm");
  EXPECT_NE(a.out.find("submitted 0 captures, 2 references, 4 points"), std::string::npos) << a.out;
  EXPECT_NE(a.out.find(": references\n"), std::string::npos) << a.out;
  EXPECT_NE(a.out.find(": points (afterok "), std::string::npos) << a.out;
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
  const Ran b =
      ropsim(root_, "study run tiny.toml --out onslurm --executor slurm --wait --slurm-throttle 1", kClusterTimeout);
  ASSERT_EQ(b.status, 0) << b.out << b.err << logs("onslurm");
  EXPECT_NE(b.out.find("3 already done, 0 failed; submitted 0 captures, 0 references, 1 points"), std::string::npos)
      << b.out;
  EXPECT_EQ(lines(slurp(root_ / "onslurm" / "slurm" / "points.txt")), 1u);
  EXPECT_EQ(lines(slurp(root_ / "onslurm" / "slurm" / "jobs.txt")), 1u);
  EXPECT_NE(slurp(root_ / "onslurm" / "slurm" / "points.sbatch").find("#SBATCH --array=0-0%1"), std::string::npos);
  EXPECT_EQ(model_results(root_, "onslurm"), want);

  // Nothing missing: nothing submitted.
  const Ran c = ropsim(root_, "study run tiny.toml --out onslurm --executor slurm", kClusterTimeout);
  EXPECT_EQ(c.status, 0) << c.out << c.err;
  EXPECT_NE(c.out.find("4 already done, 0 failed; submitted 0 captures, 0 references, 0 points"), std::string::npos)
      << c.out;
}

namespace {

/// Whether process pid runs (a zombie does not).
bool running(long pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(f, line);)
    if (line.rfind("State:", 0) == 0) return line.find('Z') == std::string::npos;
  return false;
}

long parent_of(long pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(f, line);)
    if (line.rfind("PPid:", 0) == 0) return std::stol(line.substr(5));
  return 0;
}

long read_pid(const fs::path& p) {
  std::ifstream f(p);
  long pid = 0;
  f >> pid;
  return pid;
}

/// `scontrol show job ID` (a finished job stays MinJobAge = 300 s).
std::string job_info(const fs::path& dir, const std::string& id) {
  return shell(dir, "scontrol show job " + id, 30).out;
}

/// The job id printed for a phase: "  job 12: references (afterok 11)".
std::string job_of(const std::string& out, const std::string& phase) {
  std::istringstream in(out);
  for (std::string l; std::getline(in, l);)
    if (l.rfind("  job ", 0) == 0 && l.find(": " + phase) != std::string::npos) return l.substr(6, l.find(':') - 6);
  return "";
}

}  // namespace

// A mesh input on the cluster: the captures are a first job array, the
// references follow it and the points follow them (afterok), every task with
// the study's memory request, which the node (advertising its RealMemory)
// schedules; the results are a local run's.
TEST_F(SlurmStudy, MeshInputsAreCapturedFirstAndTheJobsCarryTheMemoryRequest) {
  ASSERT_TRUE(up_) << "the SLURM cluster did not start (scripts/slurm_local.sh):\n" << why_;
  std::ofstream(root_ / "mesh.toml") << R"(
[study]
name = "mesh"

[inputs]
meshes = [")" ROPSIM_SOURCE_DIR R"(/traces/scenes/mesh/cloth.toml"]

[axes]
order = ["authored", "near-to-far"]
method = ["lk", "enderton"]
spp = 4
width = 64
height = 48

[slurm]
mem = "256M"
)";
  const Ran local = ropsim(root_, "study run mesh.toml --out mesh-local -j 2 --quiet");
  ASSERT_EQ(local.status, 0) << local.err << local.out;

  const Ran a = ropsim(root_, "study run mesh.toml --out mesh-slurm --executor slurm --wait", kClusterTimeout);
  ASSERT_EQ(a.status, 0) << a.out << a.err << logs("mesh-slurm");
  EXPECT_NE(a.out.find("submitted 2 captures, 2 references, 4 points"), std::string::npos) << a.out;
  const std::string c = job_of(a.out, "captures"), r = job_of(a.out, "references"), p = job_of(a.out, "points");
  ASSERT_FALSE(c.empty() || r.empty() || p.empty()) << a.out;
  EXPECT_NE(a.out.find("job " + r + ": references (afterok " + c + ")"), std::string::npos) << a.out;
  EXPECT_NE(a.out.find("job " + p + ": points (afterok " + r + ")"), std::string::npos) << a.out;
  EXPECT_NE(a.out.find("4 points: 4 done, 0 failed, 0 not run yet"), std::string::npos) << a.out;
  for (const char* phase : {"captures", "references", "points"}) {
    const std::string script = slurp(root_ / "mesh-slurm" / "slurm" / (std::string(phase) + ".sbatch"));
    EXPECT_NE(script.find("#SBATCH --mem=256M\n"), std::string::npos) << phase << ":\n" << script;
  }
  EXPECT_NE(slurp(root_ / "mesh-slurm" / "slurm" / "captures.sbatch").find("--kind c --index \"$index\" --recorded-ok"),
            std::string::npos);
  // The controller ran them with the request, in order: each phase started
  // once the one before had ended (SLURM's times are in whole seconds).
  auto field = [](const std::string& info, const std::string& key) {
    const size_t at = info.find(" " + key + "=");
    return at == std::string::npos
               ? std::string()
               : info.substr(at + key.size() + 2, info.find_first_of(" \n", at + 1) - at - key.size() - 2);
  };
  std::map<std::string, std::pair<std::string, std::string>> span;  // job -> (first start, last end)
  for (const auto& id : {c, r, p}) {
    const std::string info = job_info(root_, id);
    EXPECT_NE(info.find("MinMemoryNode=256M"), std::string::npos) << "job " << id << ":\n" << info;
    // One record per array task, separated by blank lines.
    std::string first = "9999", last;
    size_t at = 0;
    while ((at = info.find("JobState=", at)) != std::string::npos) {
      const std::string rec = info.substr(info.rfind("JobId=", at), info.find("\n\n", at) - info.rfind("JobId=", at));
      EXPECT_NE(rec.find("JobState=COMPLETED"), std::string::npos) << rec;
      first = std::min(first, field(rec, "StartTime"));
      last = std::max(last, field(rec, "EndTime"));
      ++at;
    }
    span[id] = {first, last};
  }
  EXPECT_GE(span[r].first, span[c].second) << "the references started before the captures ended";
  EXPECT_GE(span[p].first, span[r].second) << "the points started before the references ended";

  size_t traces = 0;
  for (const auto& e : fs::directory_iterator(root_ / "mesh-slurm" / "traces"))
    traces += e.path().extension() == ".rtr";
  EXPECT_EQ(traces, 2u) << "one capture per draw order, shared by both methods";
  // The capture a point ran, named by its folder: relative for the local
  // run (--out mesh-local), absolute on the cluster.
  auto captured = [&](Rows rows) {
    for (auto& r : rows) r["input.trace"] = fs::path(r["input.trace"]).filename().string();
    return rows;
  };
  const Rows want = captured(model_results(root_, "mesh-local"));
  ASSERT_EQ(want.size(), 4u);
  EXPECT_EQ(captured(model_results(root_, "mesh-slurm")), want)
      << "the cluster changed a result, or a point is missing or twice";
}

// More memory per task than the node has: sbatch refuses it at once, and the
// study says so in one line, with nothing left queued.
TEST_F(SlurmStudy, AMemoryRequestLargerThanTheNodeIsRefusedAtOnce) {
  ASSERT_TRUE(up_) << "the SLURM cluster did not start (scripts/slurm_local.sh):\n" << why_;
  const Ran mem = shell(root_, "sinfo -h -N -o %m", 30);
  ASSERT_EQ(mem.status, 0) << mem.err;
  const long node_mb = std::atol(mem.out.c_str());
  ASSERT_GT(node_mb, 1) << "the node advertises no RealMemory: " << mem.out;
  std::ofstream(root_ / "tiny.toml") << kStudy;
  const std::string too_much = std::to_string(node_mb + 1024) + "M";
  const Ran a =
      ropsim(root_, "study run tiny.toml --out big --executor slurm --wait --slurm-mem " + too_much, kClusterTimeout);
  EXPECT_EQ(a.status, 1) << a.out << a.err << logs("big");
  EXPECT_EQ(lines(a.err), 1u) << a.err;
  EXPECT_NE(a.err.find("ropsim: error: study run: sbatch of the references failed"), std::string::npos) << a.err;
  EXPECT_NE(a.err.find("Memory specification can not be satisfied"), std::string::npos) << a.err;
  EXPECT_NE(a.err.find("--mem=" + too_much + " per task: more than any node of the partition has"), std::string::npos)
      << a.err;
  const Ran q = shell(root_, "squeue -h", 30);
  EXPECT_EQ(q.status, 0) << q.err;
  EXPECT_EQ(q.out, "") << "jobs were left queued";
  // The node's own size is accepted.
  const Ran b = ropsim(
      root_, "study run tiny.toml --out fits --executor slurm --wait --slurm-mem " + std::to_string(node_mb) + "M",
      kClusterTimeout);
  EXPECT_EQ(b.status, 0) << b.out << b.err << logs("fits");
  EXPECT_NE(b.out.find("4 points: 4 done, 0 failed, 0 not run yet"), std::string::npos) << b.out;
}

// One input is a broken trace: its reference fails on the cluster. Its points
// record that error (they are not cancelled with the rest of the study), the
// other points complete, a second submission submits nothing, and once the
// trace is mended --retry-failed submits only the failed points (and their
// reference), each point keeping one row.
TEST_F(SlurmStudy, APointThatFailsOnTheClusterIsRecordedAndTheOthersComplete) {
  ASSERT_TRUE(up_) << "the SLURM cluster did not start (scripts/slurm_local.sh):\n" << why_;
  const Ran t = ropsim(root_, "scene eight-layers --spp 4 --width 32 --height 32 -o good.rtr");
  ASSERT_EQ(t.status, 0) << t.err;
  const std::string good = slurp(root_ / "good.rtr");
  std::ofstream(root_ / "bad.rtr", std::ios::binary) << good.substr(0, good.size() / 2);
  std::ofstream(root_ / "two.toml") << R"(
[study]
name = "two"

[inputs]
traces = ["good.rtr", "bad.rtr"]

[axes]
method = ["lk", "enderton"]
)";
  // Submitted without --wait: the test waits for the queue to empty (at most
  // 60 s), then `study collect` records what the tasks left in the folder.
  const Ran sub = ropsim(root_, "study run two.toml --out st --executor slurm", kClusterTimeout);
  ASSERT_EQ(sub.status, 0) << sub.out << sub.err;
  EXPECT_NE(sub.out.find("submitted 0 captures, 2 references, 4 points"), std::string::npos) << sub.out;
  bool empty = false;
  for (int t = 0; t < 120 && !empty; ++t) {
    const Ran q = shell(root_, "squeue -h", 30);
    empty = q.status == 0 && q.out.empty();
    if (!empty) ::usleep(500000);
  }
  ASSERT_TRUE(empty) << "the jobs did not end in 60 s\n" << logs("st");
  const Ran a = ropsim(root_, "study collect st", kClusterTimeout);
  EXPECT_EQ(a.status, 1) << "a failed point makes the exit status 1\n" << a.out << a.err << logs("st");
  EXPECT_NE(a.out.find("4 points: 2 done, 2 failed, 0 not run yet"), std::string::npos) << a.out << logs("st");
  Rows rows = model_results(root_, "st");
  ASSERT_EQ(rows.size(), 4u);
  for (const auto& row : rows) {
    if (row.at("input") == "bad") {
      EXPECT_EQ(row.at("status"), "failed");
      EXPECT_NE(row.at("error").find("its reference failed: "), std::string::npos) << row.at("error");
      // (the trace is checksummed: the cut is named by its block, docs/trace-format.md 2.3)
      EXPECT_NE(row.at("error").find("bad.rtr: block "), std::string::npos) << row.at("error");
      EXPECT_NE(a.out.find("failed: " + row.at("point") + " (bad, method=" + row.at("method") + "): its reference"),
                std::string::npos)
          << a.out;
    } else {
      EXPECT_EQ(row.at("status"), "ok") << row.at("error");
      EXPECT_FALSE(row.at("counters.samples_written").empty());
    }
  }

  // Failed points are recorded: nothing to submit.
  const Ran b = ropsim(root_, "study run two.toml --out st --executor slurm --wait", kClusterTimeout);
  EXPECT_EQ(b.status, 1) << b.out << b.err;
  EXPECT_NE(b.out.find("2 already done, 2 failed; submitted 0 captures, 0 references, 0 points"), std::string::npos)
      << b.out;
  EXPECT_EQ(model_results(root_, "st"), rows);

  // The trace mended (the input's identity is its path): only the failed
  // points and their reference are submitted again, and collected.
  std::ofstream(root_ / "bad.rtr", std::ios::binary) << good;
  const Ran c = ropsim(root_, "study run two.toml --out st --executor slurm --wait --retry-failed", kClusterTimeout);
  EXPECT_EQ(c.status, 0) << c.out << c.err << logs("st");
  EXPECT_NE(c.out.find("2 already done, 0 failed; submitted 0 captures, 1 references, 2 points"), std::string::npos)
      << c.out;
  EXPECT_NE(c.out.find("4 points: 4 done, 0 failed, 0 not run yet"), std::string::npos) << c.out;
  EXPECT_EQ(lines(slurp(root_ / "st" / "slurm" / "points.txt")), 2u);
  rows = model_results(root_, "st");
  ASSERT_EQ(rows.size(), 4u) << "a point is missing or twice";
  std::map<std::string, std::string> written;  // method -> samples written by the good input
  for (const auto& row : rows) {
    EXPECT_EQ(row.at("status"), "ok") << row.at("point") << ": " << row.at("error");
    if (row.at("input") == "good") written[row.at("method")] = row.at("counters.samples_written");
  }
  for (const auto& row : rows) {
    if (row.at("input") == "bad") {
      EXPECT_EQ(row.at("counters.samples_written"), written[row.at("method")]) << "the same trace, the same result";
    }
  }
}

// Stopping the cluster while its jobs run leaves no process of it: daemons,
// job steps and the jobs' own processes. The same when the process that
// started it dies without stopping it (a test interrupted or killed).
TEST(SlurmLocal, StopAndTheDeathOfItsOwnerLeaveNoProcessOfTheCluster) {
  Scratch s("ropsim-slurm-local");
  for (const bool by_owner : {false, true}) {
    SCOPED_TRACE(by_owner ? "the owner died" : "stop");
    const fs::path dir = s.dir / (by_owner ? "owned" : "stopped");
    // The owner: a child that the test kills (standing for the test itself).
    const pid_t owner = ::fork();
    ASSERT_GE(owner, 0);
    if (owner == 0) {
      ::execl("/bin/sleep", "sleep", "300", static_cast<char*>(nullptr));
      ::_exit(127);
    }
    const Ran up = shell(s.dir,
                         "env SLURM_LOCAL_OWNER=" + std::to_string(owner) +
                             " bash '" ROPSIM_SOURCE_DIR "/scripts/slurm_local.sh' start '" + dir.string() + "'",
                         480);
    if (up.status != 0) {
      ::kill(owner, SIGKILL);
      ::waitpid(owner, nullptr, 0);
      FAIL() << "the SLURM cluster did not start:\n" << up.out << up.err;
    }
    std::vector<long> pids;
    for (const char* f : {"munged.pid", "slurmctld.pid", "slurmd.pid"}) pids.push_back(read_pid(dir / f));
    // Two jobs that would run for a minute, each writing its shell's pid.
    const std::string conf = "env SLURM_CONF='" + (dir / "slurm.conf").string() + "' ";
    const Ran sub = shell(s.dir,
                          conf + "sbatch --parsable --array=0-1 --output=/dev/null --wrap 'echo $$ > '" +
                              s.dir.string() + "'/job$SLURM_ARRAY_TASK_ID.pid; exec sleep 60'",
                          30);
    EXPECT_EQ(sub.status, 0) << sub.err;
    int waited = sub.status == 0 ? 0 : 300;
    for (int i = 0; i < 2; ++i) {
      const fs::path pf = s.dir / ("job" + std::to_string(i) + ".pid");
      for (; waited < 300 && read_pid(pf) == 0; ++waited) ::usleep(100000);  // at most 30 s for both
      const long job = read_pid(pf);
      EXPECT_GT(job, 0) << "job task " << i << " did not start: " << sub.out << "\n"
                        << shell(s.dir, conf + "squeue", 30).out << slurp(dir / "slurmctld.log");
      if (job > 0) {
        pids.push_back(job);
        pids.push_back(parent_of(job));  // its slurmstepd
      }
      fs::remove(pf);
    }
    for (long pid : pids) EXPECT_TRUE(pid > 0 && running(pid)) << pid;
    if (by_owner) {
      ::kill(owner, SIGKILL);  // the watcher stops the cluster (it looks every second)
      ::waitpid(owner, nullptr, 0);
    } else {
      const Ran down = shell(s.dir, stop_command(dir), 60);
      EXPECT_EQ(down.status, 0) << down.err;
      ::kill(owner, SIGKILL);
      ::waitpid(owner, nullptr, 0);
    }
    std::vector<long> left;
    for (int t = 0; t < 300; ++t) {  // at most 30 s
      left.clear();
      for (long pid : pids)
        if (pid > 0 && running(pid)) left.push_back(pid);
      if (left.empty() && !fs::exists(dir)) break;
      ::usleep(100000);
    }
    std::string l;
    for (long pid : left) l += " " + std::to_string(pid) + ":" + slurp("/proc/" + std::to_string(pid) + "/cmdline");
    EXPECT_TRUE(left.empty()) << "still running:" << l;
    EXPECT_FALSE(fs::exists(dir)) << "the cluster's folder is left";
    if (!left.empty()) shell(s.dir, stop_command(dir), 60);
  }
}

// sbatch refusing a later phase (here the points) cancels the phases already
// submitted, which would otherwise run without it; its lines become one.
// Fake sbatch, squeue and scancel stand for the cluster.
TEST(StudySlurmFile, ALaterPhaseRefusedBySbatchCancelsThePhasesAlreadySubmitted) {
  Scratch s("ropsim-test-slurm-fake");
  fs::create_directories(s.dir / "bin");
  auto tool = [&](const std::string& name, const std::string& body) {
    s.put("bin/" + name, "#!/bin/sh\n" + body);
    fs::permissions(s.dir / "bin" / name, fs::perms::owner_all);
  };
  tool("sbatch", "n=$(cat '" + s.dir.string() + "/n' 2>/dev/null || echo 0); echo $((n + 1)) > '" + s.dir.string() +
                     "/n'\n"
                     "if [ \"$n\" = 0 ]; then echo 4242; exit 0; fi\n"
                     "echo 'sbatch: error: Invalid qos specification' >&2\n"
                     "echo 'sbatch: error: Batch job submission failed: Invalid qos specification' >&2\nexit 1\n");
  tool("squeue", "exit 0\n");
  tool("scancel", "echo \"$@\" >> '" + s.dir.string() + "/cancelled'\n");
  s.put("tiny.toml", kStudy);
  const Ran r = shell(s.dir,
                      "env PATH='" + (s.dir / "bin").string() +
                          ":/usr/bin:/bin' '" ROPSIM_BINARY "' study run tiny.toml --out st --executor slurm",
                      60);
  EXPECT_EQ(r.status, 1) << r.out << r.err;
  EXPECT_EQ(lines(r.err), 1u) << r.err;
  EXPECT_NE(r.err.find("sbatch of the points failed (exit status 1): sbatch: error: Invalid qos specification; "
                       "sbatch: error: Batch job submission failed: Invalid qos specification; cancelled the jobs "
                       "already submitted (4242)"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(slurp(s.dir / "cancelled"), "4242\n") << "the references' job was not cancelled";
  EXPECT_FALSE(fs::exists(s.dir / "st" / "slurm" / "jobs.txt"));
}

// --wait gives up on a job that will never run (held after a failed launch:
// the steps could not start), in one line that names it, instead of waiting
// for ever. Fake sbatch and squeue stand for the cluster.
TEST(StudySlurmFile, WaitGivesUpOnAJobThatWillNeverRun) {
  Scratch s("ropsim-test-slurm-fake");
  fs::create_directories(s.dir / "bin");
  auto tool = [&](const std::string& name, const std::string& body) {
    s.put("bin/" + name, "#!/bin/sh\n" + body);
    fs::permissions(s.dir / "bin" / name, fs::perms::owner_all);
  };
  tool("sbatch", "n=$(cat '" + s.dir.string() + "/n' 2>/dev/null || echo 7); echo $((n + 1)) > '" + s.dir.string() +
                     "/n'\necho $((n + 1))\n");
  tool("squeue", "echo '8|PENDING|launch failed requeued held'\necho '9|PENDING|Dependency'\n");
  s.put("tiny.toml", kStudy);
  const Ran r = shell(s.dir,
                      "env PATH='" + (s.dir / "bin").string() +
                          ":/usr/bin:/bin' '" ROPSIM_BINARY "' study run tiny.toml --out st --executor slurm --wait",
                      60);
  EXPECT_EQ(r.status, 1) << r.out << r.err;
  EXPECT_NE(r.out.find("job 8: references"), std::string::npos) << r.out;
  EXPECT_EQ(lines(r.err), 1u) << r.err;
  EXPECT_NE(r.err.find("ropsim: error: study run: SLURM job 8 will not run (pending: launch failed requeued held)"),
            std::string::npos)
      << r.err;
}
