// A design's memory estimate (rtl_models/top/memory_estimate.h, `ropsim config
// --json`'s memory_estimate) against the peak resident memory of real cycle
// runs, and the refusal of a design that does not fit in --memory-limit
// (docs/config.md "Memory estimate").
//
// The estimate is of the model alone, so the test compares it with the model
// alone: a design's run less the run of a tiny design (one ROP, a 256-byte
// cache, one-entry FIFOs) on the same small scene, both measured here; and
// the estimates the same way. Each run is a child process with address-space
// randomisation off, whose peak resident set (wait4's ru_maxrss) is then
// nearly the same from run to run; each figure is the median of three runs.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/personality.h>
#include <sys/ptrace.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "tests/sanitizer.h"
#include "tests/study_test_util.h"

namespace {

using namespace ropsim_test;

struct Child {
  int status = -1;          ///< exit status, -1 for a signal
  uint64_t peak_bytes = 0;  ///< its peak resident set (wait4's ru_maxrss)
  /// Its peak resident set less the file pages it maps at its exit: the peak
  /// of its anonymous memory, where the model lives (0 when /proc could not
  /// be read at its exit).
  uint64_t anon_peak_bytes = 0;
  std::string out, err;
};

std::vector<std::string> words(const std::string& s) {
  std::istringstream in(s);
  std::vector<std::string> w;
  for (std::string x; in >> x;) w.push_back(x);
  return w;
}

/// A "Key:   N kB" line of /proc/PID/status, in bytes.
uint64_t status_kb(const std::string& status, const std::string& key) {
  const auto at = status.find("\n" + key + ":");
  return at == std::string::npos ? 0 : std::stoull(status.substr(at + key.size() + 2)) * 1024;
}

/// Runs ropsim with args (split at spaces) in dir as a child process, with
/// address-space randomisation off; its exit status and peak resident set.
/// The child is traced (ptrace) only to stop it at its exit, while its
/// memory is still there: its /proc status then gives the peak (VmHWM) and
/// the file pages (RssFile, RssShmem), whose number depends a little on what
/// the machine's page cache holds.
Child run_child(const fs::path& dir, const std::string& args) {
  const std::string out = (dir / ".child.out").string(), err = (dir / ".child.err").string();
  std::vector<std::string> a = words(args);
  a.insert(a.begin(), ROPSIM_BINARY);
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (::chdir(dir.c_str()) != 0) _exit(126);
    ::personality(ADDR_NO_RANDOMIZE);  // where refused, the peak varies by a few pages
    const int o = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int e = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (o < 0 || e < 0 || ::dup2(o, 1) < 0 || ::dup2(e, 2) < 0) _exit(126);
    ::ptrace(PTRACE_TRACEME, 0, nullptr, nullptr);  // refused: no stop at exec, nor at exit
    std::vector<char*> argv;
    for (auto& s : a) argv.push_back(s.data());
    argv.push_back(nullptr);
    ::execv(argv[0], argv.data());
    _exit(127);
  }
  Child c;
  if (pid < 0) return c;
  int st = 0;
  struct rusage ru {};
  for (;;) {
    if (::wait4(pid, &st, 0, &ru) != pid) return c;
    if (!WIFSTOPPED(st)) break;
    int deliver = 0;
    if (WSTOPSIG(st) == SIGTRAP && (st >> 16) == PTRACE_EVENT_EXIT) {
      const std::string status = "\n" + slurp("/proc/" + std::to_string(pid) + "/status");
      const uint64_t hwm = status_kb(status, "VmHWM"),
                     files = status_kb(status, "RssFile") + status_kb(status, "RssShmem");
      if (hwm > files) c.anon_peak_bytes = hwm - files;
    } else if (WSTOPSIG(st) == SIGTRAP && (st >> 16) == 0 && c.status == -1) {
      ::ptrace(PTRACE_SETOPTIONS, pid, nullptr, reinterpret_cast<void*>(long(PTRACE_O_TRACEEXIT)));  // the exec's stop
      c.status = -2;
    } else {
      deliver = WSTOPSIG(st);  // a signal of its own: passed on
    }
    ::ptrace(PTRACE_CONT, pid, nullptr, reinterpret_cast<void*>(long(deliver)));
  }
  c.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  c.peak_bytes = uint64_t(ru.ru_maxrss) * 1024;  // KiB on Linux
  c.out = slurp(out);
  c.err = slurp(err);
  return c;
}

/// The small built-in scene every measured run draws, and the screen the estimates assume.
const char* kScene = "--scene smoke --spp 4 --width 64 --height 64";
const char* kShape = "--width 64 --height 64 --spp 4";

/// The tiny design the model is measured against (no compression, no Hi-Z).
const char* kTiny =
    "--hw-set distributor.rop_units=1 --hw-set cache.size_bytes=256 --hw-set cache.ways=1 --hw-set source.fifo_depth=1 "
    "--hw-set distributor.fifo_depth=1 --hw-set ordering.window=1 --hw-set ordering.fifo_depth=1 "
    "--hw-set depth_test.max_outstanding=1 --hw-set depth_test.fifo_depth=1 --hw-set tracker.fifo_depth=1 "
    "--hw-set sorter.fifo_depth=1 --hw-set alpha_ref.fifo_depth=1 --hw-set ordering.pixels_in_flight=1 "
    "--hw-set compression.depth=false --hw-set compression.color=false --hw-set hiz.enable=false";

struct Design {
  std::string name;
  std::string file;  ///< a design file, or empty
  std::string sets;  ///< --hw-set flags
};

std::vector<Design> measured_designs() {
  std::vector<Design> d;
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(fs::path(ROPSIM_SOURCE_DIR) / "configs"))
    if (e.path().extension() == ".toml") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  for (const auto& f : files) d.push_back({"configs/" + f.filename().string(), f.string(), ""});
  d.push_back({"64 ROPs, default caches", "", "--hw-set distributor.rop_units=64"});
  return d;
}

/// config --json's memory_estimate of a design.
nlohmann::json estimate_of(const fs::path& dir, const std::string& design_args) {
  const Ran r = ropsim(dir, "config " + design_args + " " + kShape + " --json", 60);
  EXPECT_EQ(r.status, 0) << r.err;
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(r.out).at("memory_estimate");
  } catch (const std::exception& e) {
    ADD_FAILURE() << "config --json has no memory_estimate: " << e.what() << "\n" << r.out.substr(0, 400);
  }
  return j;
}

uint64_t total_of(const nlohmann::json& e) { return e.is_object() ? e.value("total_bytes", uint64_t{0}) : 0; }

/// The peak of a cycle run of a design on the small scene: its anonymous
/// memory's (its resident set's without file pages; the whole resident set
/// where the child's status could not be read at its exit), the median of
/// three runs.
uint64_t peak_of(const fs::path& dir, const std::string& design_args) {
  std::vector<uint64_t> peaks;
  for (int i = 0; i < 3; ++i) {
    const Child c = run_child(dir, "--threads 1 run --fidelity cycle " + std::string(kScene) + " " + design_args +
                                       " --quiet --report r.json");
    EXPECT_EQ(c.status, 0) << design_args << ": " << c.err;
    EXPECT_GT(c.peak_bytes, 0u) << "no peak resident set from wait4";
    peaks.push_back(c.anon_peak_bytes ? c.anon_peak_bytes : c.peak_bytes);
  }
  std::sort(peaks.begin(), peaks.end());
  return peaks[1];
}

// (The source folder's path has no spaces: the arguments are split at spaces.)
std::string design_args(const Design& d) { return (d.file.empty() ? "" : "--hw " + d.file + " ") + d.sets; }
std::string config_args(const Design& d) { return (d.file.empty() ? "" : d.file + " ") + d.sets; }

/// The kernel keeps a process's resident-page counts per CPU and folds them
/// into the peak in batches (tens of pages), so a peak is known to about
/// 128 KiB and a difference of two to 256 KiB (runs of one design differ by
/// up to 128 KiB here).
constexpr double kResolution = 256 * 1024;

}  // namespace

// For every committed design and a 64-ROP design with the default caches,
// the estimated model (its estimate less the tiny design's) is within 25 %
// (and 256 KiB, the measurement's resolution) of the measured model (its
// run's peak anonymous memory less the tiny design's run's). The 64-ROP
// design's model (10 MiB) and wide's (2 MiB) are well above the resolution.
TEST(MemoryEstimate, ModelAloneWithin25PercentOfMeasuredPeak) {
#ifdef ROPSIM_TEST_ASAN
  GTEST_SKIP() << "AddressSanitizer's redzones and shadow memory are in every resident set: the normal build "
                  "measures the model's memory";
#endif
  Scratch s("ropsim-test-memest");
  const uint64_t tiny_peak = peak_of(s.dir, kTiny);
  const uint64_t tiny_est = total_of(estimate_of(s.dir, kTiny));
  ASSERT_GT(tiny_peak, 0u) << "no peak resident set from wait4";
  ASSERT_GT(tiny_est, 0u);
  std::printf("| design | estimate (model) | measured (model) | estimate / measured |\n|---|---:|---:|---:|\n");
  for (const Design& d : measured_designs()) {
    SCOPED_TRACE(d.name);
    const uint64_t est = total_of(estimate_of(s.dir, config_args(d)));
    const uint64_t peak = peak_of(s.dir, design_args(d));
    const double e = double(est) - double(tiny_est), m = double(peak) - double(tiny_peak);
    std::printf("| %s | %.0f | %.0f | %.3f |\n", d.name.c_str(), e, m, m > 0 ? e / m : 0.0);
    EXPECT_LE(std::fabs(e - m), 0.25 * std::fabs(m) + kResolution)
        << "the estimate's model is " << e << " bytes, the measured model " << m << " bytes (" << d.name << ": peak "
        << peak << " bytes against the tiny design's " << tiny_peak << ")";
    if (!d.sets.empty()) {
      EXPECT_GT(m, 4e6) << "the 64-ROP model is large enough to measure (a few MiB): " << m << " bytes";
    }
  }
}

// The design of 64 ROPs with 1 GiB caches of 16-byte lines (64 ways), inside
// every parameter's range, is refused under the default limit before any
// work, in one line naming the overrides and the keys that cost the most;
// from a design file, the line names the file. --memory-limit 256M refuses a
// design that needs more (a 256 MiB cache per ROP), and still runs one that
// needs less.
TEST(MemoryEstimate, RefusesADesignOverTheLimit) {
  Scratch s("ropsim-test-memest");
  const std::string huge =
      "--hw-set distributor.rop_units=64 --hw-set cache.size_bytes=1073741824 --hw-set cache.line_bytes=16 "
      "--hw-set cache.ways=64";
  const nlohmann::json e = estimate_of(s.dir, huge);
  const uint64_t need = total_of(e);
  // 64 ROPs x 2^26 lines x 32 bytes (a tag and an LRU time, 16; the line's state, 16): 128 GiB.
  EXPECT_GT(need, uint64_t{120} << 30) << "the estimate of the 64-ROP, 1 GiB-cache design: " << e.dump();
  ASSERT_TRUE(e.contains("parts")) << e.dump();
  EXPECT_GE(e["parts"]["cache_tags"]["per_rop_bytes"].get<uint64_t>(), uint64_t{1} << 30) << e.dump();
  const Ran human = ropsim(s.dir, "config " + huge, 60);
  EXPECT_NE(human.out.find("# memory estimate of the cycle model"), std::string::npos) << human.out;

  auto expect_refused = [&](const std::string& args, const std::vector<std::string>& named) {
    SCOPED_TRACE(args);
    const Ran r = ropsim(s.dir, args + " --quiet --report refused.json", 120);
    EXPECT_EQ(r.status, 1) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << "not one line: " << r.err;
    EXPECT_EQ(r.err.rfind("ropsim: error: ", 0), 0u) << r.err;
    for (const std::string& n : named)
      EXPECT_NE(r.err.find(n), std::string::npos) << "does not name " << n << ": " << r.err;
    EXPECT_FALSE(fs::exists(s.dir / "refused.json")) << "a refused run wrote its report";
  };
  const uint64_t limit = e.value("memory_limit_bytes", uint64_t{0});
  if (limit != 0 && need > limit) {
    expect_refused("run --fidelity cycle --scene smoke --spp 4 " + huge,
                   {"--hw-set distributor.rop_units=64", "--hw-set cache.size_bytes=1073741824",
                    "--hw-set cache.line_bytes=16", "cache.size_bytes", "distributor.rop_units", "--memory-limit"});
    expect_refused("run --fidelity approximate --scene smoke --spp 4 " + huge, {"cache.size_bytes"});
    const fs::path file = s.put("huge.toml",
                                "[distributor]\nrop_units = 64\n[cache]\nsize_bytes = 1073741824\nline_bytes = 16\n"
                                "ways = 64\n");
    expect_refused("run --fidelity cycle --scene smoke --spp 4 --hw " + file.string(),
                   {file.string() + ":", "cache.line_bytes"});
  } else {
    EXPECT_TRUE(e.value("fits_memory_limit", false)) << "this machine's default limit holds the design: " << e.dump();
  }

  const std::string big = "--hw-set cache.size_bytes=268435456";  // 4 ROPs x 4 Mi lines
  EXPECT_GT(total_of(estimate_of(s.dir, big)), uint64_t{256} << 20);
  expect_refused("--memory-limit 256M run --fidelity cycle --scene smoke --spp 4 " + big,
                 {"--hw-set cache.size_bytes=268435456", "256.0 MiB", "cache.line_bytes"});
  expect_refused("--memory-limit 256M run --fidelity sampled --scene smoke --spp 4 --jobs 1 " + big,
                 {"--hw-set cache.size_bytes=268435456"});
  const Ran fits =
      ropsim(s.dir, "--memory-limit 256M run --fidelity cycle --scene smoke --spp 4 --quiet --report ok.json", 120);
  EXPECT_EQ(fits.status, 0) << "the default design fits in 256 MiB: " << fits.err;
}
