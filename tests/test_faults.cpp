// Fault injection (docs/testing.md "Fault injection"): every output kind --
// image, report, trace, capture, VCD, study database -- under a full disk, a
// kill -9 at random points, and concurrent writers, leaves a complete result
// or nothing under its name, and says why in one line.
//
// The full disk is real: a small tmpfs mounted for the test (ropsim's tests run
// as root, scripts/test.sh). Where mounting is not permitted the full-disk test
// is skipped and says so; Output.FileSizeLimitIsAUserErrorForEveryKindAndLeavesNoFile
// (test_output.cpp) covers the same paths with `ulimit -f`.
#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/mount.h>
#include <sys/statvfs.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <random>
#include <thread>

#include "sim/image/image_io.h"
#include "tests/study_test_util.h"

#ifndef ROPSIM_SOURCE_DIR
#error "ROPSIM_SOURCE_DIR must name the source tree (tests/CMakeLists.txt)"
#endif

namespace {

using namespace ropsim_test;

const char* kStudy = R"(
[inputs]
scenes = ["eight-layers"]

[axes]
method = ["lk", "enderton", "naive", "a2c"]
spp = [4, 8, 16]
width = 32
height = 32
)";

/// Files under dir other than those named (temporary files a failed writer left).
std::vector<std::string> strays(const fs::path& dir, const std::vector<std::string>& allowed = {}) {
  std::vector<std::string> v;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    const std::string rel = fs::relative(e.path(), dir).string();
    if (std::find(allowed.begin(), allowed.end(), rel) == allowed.end()) v.push_back(rel);
  }
  return v;
}

/// "" if path is a SQLite database that passes its integrity check, else why not.
std::string db_problem(const fs::path& path) {
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
    sqlite3_close(db);
    return "cannot open";
  }
  std::string result;
  sqlite3_exec(
      db, "PRAGMA integrity_check",
      [](void* r, int, char** v, char**) {
        *static_cast<std::string*>(r) += v[0] ? v[0] : "";
        return 0;
      },
      &result, nullptr);
  sqlite3_close(db);
  return result == "ok" ? "" : "integrity check: " + result;
}

/// A tmpfs of `bytes` mounted at dir for the test's lifetime.
struct SmallDisk {
  fs::path dir;
  bool mounted = false;
  std::string why;
  SmallDisk(const fs::path& d, size_t bytes) : dir(d) {
    fs::create_directories(dir);
    const std::string opt = "size=" + std::to_string(bytes) + ",mode=0755";
    if (::mount("tmpfs", dir.c_str(), "tmpfs", 0, opt.c_str()) == 0)
      mounted = true;
    else
      why = std::string("cannot mount a tmpfs: ") + std::strerror(errno);
  }
  ~SmallDisk() {
    if (mounted) ::umount2(dir.c_str(), MNT_DETACH);
  }
  /// Fills the disk until at most `leave` bytes are free (a file named
  /// .filler); tmpfs allocates whole pages, so leave 0 means no room at all.
  void fill_leaving(size_t leave) const {
    fs::remove(dir / ".filler");
    struct statvfs s {};
    ::statvfs(dir.c_str(), &s);
    const size_t avail = size_t(s.f_bavail) * s.f_frsize;
    std::ofstream f(dir / ".filler", std::ios::binary);
    const std::string block(4096, 'x');
    for (size_t n = 0; n + block.size() + leave <= avail; n += block.size()) f << block;
    f.flush();
    if (leave == 0) f << 'x' << std::flush;  // the last partial page, if any: up to ENOSPC
  }
};

TEST(Faults, AFullDiskIsAOneLineErrorForEveryOutputAndLeavesNothing) {
  Scratch s("ropsim-test-faults");
  SmallDisk disk(s.dir / "full", 2u << 20);
  if (!disk.mounted) GTEST_SKIP() << disk.why;
  s.put("s.toml", kStudy);
  const std::string scene = ROPSIM_SOURCE_DIR "/traces/scenes/mesh/cloth.toml";
  struct Case {
    const char* kind;
    std::string cmd;
    std::string output;  ///< under full/
  };
  const std::vector<Case> cases = {
      {"png", "run --scene cloth --spp 4 --quiet --out full/x.png --report r.json", "x.png"},
      {"exr", "run --scene cloth --spp 4 --quiet --out full/x.exr --report r.json", "x.exr"},
      {"report", "run --scene cloth --spp 4 --quiet --out o.png --report full/x.json", "x.json"},
      {"trace", "scene cloth --spp 16 -o full/x.rtrace", "x.rtrace"},
      {"capture", "capture '" + scene + "' --spp 4 --width 160 --height 120 -o full/x.rtrace --quiet", "x.rtrace"},
      {"vcd", "run --scene cloth --spp 4 --fidelity cycle --quiet --vcd full/x.vcd --out o.png", "x.vcd"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.kind);
    disk.fill_leaving(0);  // no page left: any byte written fails
    const Ran r = ropsim_test::ropsim(s.dir, c.cmd, 120);
    EXPECT_EQ(r.status, 1) << c.cmd << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << "not one line:\n" << r.err;
    EXPECT_NE(r.err.find("full/" + c.output), std::string::npos) << "the error does not name the file:\n" << r.err;
    EXPECT_NE(r.err.find(std::strerror(ENOSPC)), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(disk.dir / c.output)) << "a partial " << c.kind << " under its name";
    const auto left = strays(disk.dir, {".filler"});
    EXPECT_TRUE(left.empty()) << "left behind: " << left.front();
  }
  // A study: its database stays whole on a full disk, and the study completes
  // once there is room, every point once.
  disk.fill_leaving(8192);
  const Ran r = ropsim_test::ropsim(s.dir, "study run s.toml --out full/st -j 2 --quiet", 120);
  EXPECT_NE(r.status, 0) << "a study ran to the end on a full disk";
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << "not one line:\n" << r.err;
  if (fs::exists(disk.dir / "st" / "results.db")) {
    EXPECT_EQ(db_problem(disk.dir / "st" / "results.db"), "");
  }
  fs::remove(disk.dir / ".filler");
  const Ran again = ropsim_test::ropsim(s.dir, "study run s.toml --out full/st -j 2 --quiet", 120);
  ASSERT_EQ(again.status, 0) << again.err;
  EXPECT_EQ(db_problem(disk.dir / "st" / "results.db"), "");
  const Rows rows = export_rows(s.dir, "full/st");
  EXPECT_EQ(rows.size(), 12u) << "every point once";
}

TEST(Faults, TwoStudyRunsOnOneFolderOneWaitsOutAndEveryPointIsRecordedOnce) {
  Scratch s("ropsim-test-faults");
  s.put("s.toml", kStudy);
  for (int round = 0; round < 3; ++round) {
    fs::remove_all(s.dir / "st");
    const std::string cmd = "'" ROPSIM_BINARY "' study run s.toml --out st -j 1 --quiet";
    s.put("both.sh", "(" + cmd + " 2>e1; echo $? >s1) & (" + cmd + " 2>e2; echo $? >s2) & wait\n");
    const Ran r = shell(s.dir, "sh both.sh", 120);
    ASSERT_EQ(r.status, 0) << r.err;
    const int s1 = std::stoi(slurp(s.dir / "s1")), s2 = std::stoi(slurp(s.dir / "s2"));
    EXPECT_TRUE(s1 == 0 || s2 == 0) << "neither run completed\n" << slurp(s.dir / "e1") << slurp(s.dir / "e2");
    for (const auto& [st, e] : {std::pair{s1, "e1"}, std::pair{s2, "e2"}})
      if (st != 0) {
        const std::string err = slurp(s.dir / e);
        EXPECT_EQ(st, 1) << err;
        EXPECT_NE(err.find("st: another ropsim is running or collecting a study in this folder"), std::string::npos)
            << err;
      }
    EXPECT_EQ(db_problem(s.dir / "st" / "results.db"), "");
    EXPECT_EQ(export_rows(s.dir, "st").size(), 12u) << "every point once";
  }
}

/// Runs cmd in dir, kills it with SIGKILL after `delay` (none: lets it
/// finish), and waits for it. Returns true if the signal ended it.
bool kill_after(const fs::path& dir, const std::string& args, std::chrono::microseconds delay) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (::chdir(dir.c_str()) != 0) ::_exit(127);
    ::execl("/bin/sh", "sh", "-c", ("exec '" ROPSIM_BINARY "' " + args + " >/dev/null 2>&1").c_str(), nullptr);
    ::_exit(127);
  }
  if (delay.count() > 0) {
    std::this_thread::sleep_for(delay);
    ::kill(pid, SIGKILL);
  }
  int st = 0;
  ::waitpid(pid, &st, 0);
  return WIFSIGNALED(st);
}

TEST(Faults, AKillAtRandomPointsLeavesEachOutputCompleteOrAbsent) {
  Scratch s("ropsim-test-faults");
  const std::string scene = ROPSIM_SOURCE_DIR "/traces/scenes/mesh/cloth.toml";
  struct Case {
    const char* kind;
    std::string cmd;
    std::vector<std::string> outputs;
  };
  const std::vector<Case> cases = {
      {"run", "run --scene cloth --spp 16 --quiet --out o.exr --report o.json", {"o.exr", "o.json"}},
      {"cycle run",
       "run --scene cloth --spp 4 --fidelity cycle --quiet --out c.png --report c.json --vcd c.vcd",
       {"c.png", "c.json", "c.vcd"}},
      {"scene", "scene cloth --spp 16 -o t.rtrace", {"t.rtrace"}},
      {"capture", "capture '" + scene + "' --spp 4 --width 320 --height 240 -o m.rtrace --quiet", {"m.rtrace"}},
  };
  std::mt19937 rng(20261129);  // fixed: the same kill points every run
  int killed = 0;
  for (const auto& c : cases) {
    SCOPED_TRACE(c.kind);
    // The kill points are fractions of the command's own duration, measured
    // once here, so they fall within it on any machine.
    const auto t0 = std::chrono::steady_clock::now();
    ASSERT_FALSE(kill_after(s.dir, c.cmd, std::chrono::microseconds(0)));
    const auto whole = std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::steady_clock::now() - t0);
    for (int k = 0; k < 8; ++k) {
      for (const auto& o : c.outputs) fs::remove(s.dir / o);
      const auto delay = std::chrono::microseconds(
          1 + int64_t(std::uniform_real_distribution<double>(0.0, 1.0)(rng) * double(whole.count())));
      killed += kill_after(s.dir, c.cmd, delay);
      for (const auto& o : c.outputs) {
        const fs::path p = s.dir / o;
        if (!fs::exists(p)) continue;
        const std::string ext = p.extension().string();
        if (ext == ".json") {
          const std::string t = slurp(p);
          EXPECT_TRUE(!t.empty() && t.find("\"counters\"") != std::string::npos && t.back() == '\n')
              << o << " incomplete after a kill at " << delay.count() << " us";
        } else if (ext == ".png" || ext == ".exr") {
          EXPECT_NO_THROW(ropsim::read_image(p.string())) << o << " unreadable after a kill at " << delay.count();
        } else if (ext == ".vcd") {
          EXPECT_NE(slurp(p).find("$enddefinitions"), std::string::npos) << o << " incomplete after a kill";
        } else {
          const Ran v = ropsim_test::ropsim(s.dir, "trace validate " + o, 60);
          EXPECT_EQ(v.status, 0) << o << " incomplete after a kill at " << delay.count() << " us: " << v.err;
        }
      }
    }
  }
  EXPECT_GE(killed, 16) << "fewer than half the runs were still going when killed: the test proves little";
}

}  // namespace
