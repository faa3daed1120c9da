// The output writer (util/output_file.h) and the exit statuses (README "Exit
// status"), tested through the real ropsim binary run with fork/exec in a
// private folder, with a private $TMPDIR. Nothing here writes to /dev/null
// through the writer (a failing test could replace it): device-like targets
// are FIFOs made by the test.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "sim/image/image_io.h"
#include "tests/compare_util.h"
#include "traces/format/trace.h"
#include "util/errors.h"
#include "util/output_file.h"

#ifndef ROPSIM_BINARY
#error "ROPSIM_BINARY must name the built ropsim executable (tests/CMakeLists.txt)"
#endif

extern char** environ;

namespace fs = std::filesystem;

namespace {

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

std::vector<std::string> lines_of(const std::string& s) {
  std::vector<std::string> v;
  std::istringstream in(s);
  for (std::string l; std::getline(in, l);) v.push_back(l);
  return v;
}

struct Result {
  int code = -1;   ///< exit status; -1 when killed by a signal
  int signal = 0;  ///< the signal that killed it
  std::string out, err, cmd;
  std::string describe() const {
    return cmd + "\n" + (signal ? "killed by signal " + std::to_string(signal) : "exit " + std::to_string(code)) +
           "\nstdout:\n" + out.substr(0, 2000) + "stderr:\n" + err.substr(0, 2000);
  }
};

struct RunOptions {
  long fsize_limit = -1;  ///< RLIMIT_FSIZE in bytes for the child
  std::vector<std::string> env;
  int stdout_fd = -1;       ///< >= 0: the child's standard output (else io/<tag>.out)
  std::string stdout_path;  ///< non-empty: opened for writing as the child's standard output
  int umask = -1;           ///< >= 0: the child's umask
};

/// A private folder: work/ (ropsim's working directory: only what it writes),
/// io/ (captured stdout and stderr), tmp/ (ropsim's $TMPDIR).
class Box {
 public:
  Box() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() /
            ("ropsim-test-output-" + std::to_string(::getpid()) + "-" + (info ? std::string(info->name()) : "x"));
    fs::remove_all(root_);
    for (const char* d : {"work", "io", "tmp"}) fs::create_directories(root_ / d);
  }
  ~Box() {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }
  fs::path work() const { return root_ / "work"; }
  fs::path tmp() const { return root_ / "tmp"; }
  std::string path(const std::string& f) const { return (work() / f).string(); }

  using Options = RunOptions;

  /// Starts ropsim ARGS in work/; stdout and stderr go to io/<tag>.out/.err.
  pid_t start(const std::vector<std::string>& args, const std::string& tag, const Options& o = Options()) const {
    std::vector<std::string> argv_s = {ROPSIM_BINARY};
    argv_s.insert(argv_s.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : argv_s) argv.push_back(a.data());
    argv.push_back(nullptr);
    std::vector<std::string> env_s;
    for (char** e = environ; *e; ++e)
      if (std::strncmp(*e, "TMPDIR=", 7) != 0 && std::strncmp(*e, "ROPSIM_TEST_INTERNAL_ERROR=", 27) != 0)
        env_s.push_back(*e);
    env_s.push_back("TMPDIR=" + tmp().string());
    env_s.insert(env_s.end(), o.env.begin(), o.env.end());
    std::vector<char*> envp;
    for (auto& e : env_s) envp.push_back(e.data());
    envp.push_back(nullptr);
    const std::string wd = work().string(), out = (root_ / "io" / (tag + ".out")).string(),
                      err = (root_ / "io" / (tag + ".err")).string();
    const pid_t pid = ::fork();
    if (pid == 0) {  // only async-signal-safe calls from here
      if (::chdir(wd.c_str()) != 0) ::_exit(126);
      const int in = ::open("/dev/null", O_RDONLY);
      const int fo = o.stdout_fd >= 0         ? o.stdout_fd
                     : !o.stdout_path.empty() ? ::open(o.stdout_path.c_str(), O_WRONLY)
                                              : ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      const int fe = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (in < 0 || fo < 0 || fe < 0) ::_exit(126);
      ::dup2(in, 0);
      ::dup2(fo, 1);
      ::dup2(fe, 2);
      if (o.umask >= 0) ::umask(mode_t(o.umask));
      if (o.fsize_limit >= 0) {
        struct rlimit rl;
        rl.rlim_cur = rl.rlim_max = rlim_t(o.fsize_limit);
        ::setrlimit(RLIMIT_FSIZE, &rl);
      }
      ::execve(argv[0], argv.data(), envp.data());
      ::_exit(127);
    }
    return pid;
  }

  Result wait(pid_t pid, const std::string& tag, const std::vector<std::string>& args) const {
    Result r;
    int st = 0;
    while (::waitpid(pid, &st, 0) < 0 && errno == EINTR) {
    }
    if (WIFEXITED(st)) r.code = WEXITSTATUS(st);
    if (WIFSIGNALED(st)) r.signal = WTERMSIG(st);
    if (fs::exists(root_ / "io" / (tag + ".out"))) r.out = slurp(root_ / "io" / (tag + ".out"));
    r.err = slurp(root_ / "io" / (tag + ".err"));
    r.cmd = "ropsim";
    for (const auto& a : args) r.cmd += " " + a;
    return r;
  }

  Result run(const std::vector<std::string>& args, const Options& o = Options()) const {
    return wait(start(args, "run", o), "run", args);
  }

  /// Names in work/ and tmp/ that look like the writer's temporary files.
  std::vector<std::string> leftovers() const {
    std::vector<std::string> v;
    for (const auto& e : fs::recursive_directory_iterator(work()))
      if (e.path().filename().string()[0] == '.') v.push_back(e.path().string());
    for (const auto& e : fs::directory_iterator(tmp())) v.push_back(e.path().string());
    return v;
  }

 private:
  fs::path root_;
};

const std::vector<std::string> kSmall = {"--width", "64", "--height", "64", "--spp", "4"};

std::vector<std::string> cat(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

/// "" when path is a complete, valid trace; else the reader's message.
std::string trace_problem(const std::string& path) {
  try {
    ropsim::TraceReader r(path);
    ropsim::Fragment f;
    while (r.next(f)) {
    }
    if (r.records_read() == 0) return "no records";
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

std::string json_problem(const std::string& text) {
  try {
    auto j = nlohmann::json::parse(text);
    if (!j.contains("counters")) return "no counters";
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

std::string image_problem(const std::string& path) {
  try {
    ropsim::Image img = ropsim::read_image(path);
    if (img.width != 64 || img.height != 64) return "wrong size";
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

bool is_fifo(const std::string& p) {
  struct stat st;
  return ::lstat(p.c_str(), &st) == 0 && S_ISFIFO(st.st_mode);
}

// ------------------------------------------------------------ targets

TEST(Output, FifoTargetReceivesTheReportAndStaysAFifo) {
  Box box;
  const std::string fifo = box.path("report.json");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0) << std::strerror(errno);
  std::string got;
  std::thread reader([&] {
    const int fd = ::open(fifo.c_str(), O_RDONLY);
    if (fd < 0) return;
    char buf[4096];
    for (ssize_t n; (n = ::read(fd, buf, sizeof buf)) > 0;) got.append(buf, size_t(n));
    ::close(fd);
  });
  const auto args = cat({"run", "--scene", "cloth", "--report", "report.json", "--quiet"}, kSmall);
  const Result r = box.run(args);
  // Unblock the reader if ropsim never opened the FIFO.
  const int fd = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK);
  if (fd >= 0) ::close(fd);
  reader.join();
  EXPECT_EQ(r.code, 0) << r.describe();
  EXPECT_TRUE(is_fifo(fifo)) << "the FIFO was replaced by a regular file";
  EXPECT_EQ(json_problem(got), "") << "the FIFO's reader got:\n" << got.substr(0, 500);
  EXPECT_TRUE(box.leftovers().empty()) << box.leftovers()[0];
}

TEST(Output, SymlinkTargetKeepsTheLinkAndGetsNewContents) {
  Box box;
  fs::create_directories(box.work() / "real");
  std::ofstream(box.path("real/r.json")) << "old";
  std::ofstream(box.path("real/t.trace")) << "old";
  fs::create_symlink("real/r.json", box.path("link.json"));             // relative links,
  fs::create_symlink("link.json", box.path("chain.json"));              // and a chain
  fs::create_symlink(box.path("real/t.trace"), box.path("abs.trace"));  // an absolute one
  const Result r = box.run(cat({"run", "--scene", "cloth", "--report", "chain.json", "--quiet"}, kSmall));
  EXPECT_EQ(r.code, 0) << r.describe();
  const Result s = box.run(cat({"scene", "cloth", "-o", "abs.trace"}, kSmall));
  EXPECT_EQ(s.code, 0) << s.describe();
  EXPECT_TRUE(fs::is_symlink(box.path("chain.json")));
  EXPECT_TRUE(fs::is_symlink(box.path("link.json")));
  EXPECT_TRUE(fs::is_symlink(box.path("abs.trace")));
  EXPECT_EQ(fs::read_symlink(box.path("link.json")), "real/r.json");
  EXPECT_TRUE(fs::is_regular_file(fs::symlink_status(box.path("real/r.json"))));
  EXPECT_EQ(json_problem(slurp(box.path("real/r.json"))), "") << "the link's target did not get the report";
  EXPECT_EQ(trace_problem(box.path("real/t.trace")), "") << "the link's target did not get the trace";
  EXPECT_TRUE(box.leftovers().empty()) << box.leftovers()[0];
}

TEST(Output, DashWritesTheReportAndTheDumpToStandardOutput) {
  Box box;
  const Result r = box.run(cat({"run", "--scene", "cloth", "--report", "-", "--out", "a.png"}, kSmall));
  EXPECT_EQ(r.code, 0) << r.describe();
  EXPECT_EQ(json_problem(r.out), "") << "stdout is not the report alone:\n" << r.out.substr(0, 500);
  const auto j = nlohmann::json::parse(r.out, nullptr, false);
  ASSERT_FALSE(j.is_discarded());
  // Every report carries the version and the source commit.
  EXPECT_TRUE(j.contains("ropsim") && j["ropsim"]["version"].is_string() && j["ropsim"]["commit"].is_string() &&
              !j["ropsim"]["commit"].get<std::string>().empty())
      << j.dump().substr(0, 300);
  EXPECT_FALSE(fs::exists(box.path("-"))) << "a file named '-' was written";
  EXPECT_EQ(image_problem(box.path("a.png")), "");
  ASSERT_EQ(box.run(cat({"scene", "cloth", "-o", "s.trace"}, kSmall)).code, 0);
  for (const auto& args : std::vector<std::vector<std::string>>{
           {"trace", "dump", "s.trace", "--limit", "3"}, {"trace", "dump", "s.trace", "--limit", "3", "-o", "-"}}) {
    const Result d = box.run(args);
    EXPECT_EQ(d.code, 0) << d.describe();
    EXPECT_EQ(lines_of(d.out).size(), 4u) << "header + 3 fragments expected\n" << d.describe();
  }
  EXPECT_FALSE(fs::exists(box.path("-")));
}

// ------------------------------------------------------------ concurrency

TEST(Output, ConcurrentRunsOnOnePathNeverLeaveAPartialFile) {
  Box box;
  for (int round = 0; round < 20; ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    // Two pairs at once: two scene writers on one trace, two runs on one report and image.
    std::vector<std::vector<std::string>> cmds;
    for (int k = 0; k < 2; ++k) {
      cmds.push_back(cat({"scene", "cloth", "--seed", std::to_string(k + 1), "-o", "same.trace"}, kSmall));
      cmds.push_back(cat({"run", "--scene", "cloth", "--seed", std::to_string(k + 1), "--report", "same.json", "--out",
                          "same.png", "--quiet"},
                         kSmall));
    }
    std::vector<pid_t> pids;
    for (size_t i = 0; i < cmds.size(); ++i) pids.push_back(box.start(cmds[i], "c" + std::to_string(i)));
    for (size_t i = 0; i < cmds.size(); ++i) {
      const Result r = box.wait(pids[i], "c" + std::to_string(i), cmds[i]);
      EXPECT_EQ(r.signal, 0) << r.describe();
      if (r.code != 0) {  // an error is allowed, but as one line
        EXPECT_EQ(r.err.rfind("ropsim: error: ", 0), 0u) << r.describe();
      }
    }
    EXPECT_EQ(trace_problem(box.path("same.trace")), "");
    EXPECT_EQ(json_problem(slurp(box.path("same.json"))), "");
    EXPECT_EQ(image_problem(box.path("same.png")), "");
    const auto left = box.leftovers();
    EXPECT_TRUE(left.empty()) << left[0];
    if (::testing::Test::HasFailure()) break;
  }
}

// ------------------------------------------------------------ write errors

TEST(Output, FileSizeLimitIsAUserErrorForEveryKindAndLeavesNoFile) {
  Box box;
  struct Case {
    const char* kind;
    std::vector<std::string> args;
    std::vector<std::string> must_not_exist;
  };
  const std::vector<Case> cases = {
      {"png", cat({"run", "--scene", "cloth", "--out", "x.png", "--quiet"}, kSmall), {"x.png"}},
      {"exr", cat({"run", "--scene", "cloth", "--out", "x.exr", "--quiet"}, kSmall), {"x.exr"}},
      {"report", cat({"run", "--scene", "cloth", "--report", "x.json", "--quiet"}, kSmall), {"x.json"}},
      {"trace", cat({"scene", "cloth", "-o", "x.trace"}, kSmall), {"x.trace"}},
      {"vcd",
       cat({"run", "--scene", "cloth", "--fidelity", "cycle", "--vcd", "x.vcd", "--out", "v.png", "--quiet"}, kSmall),
       {"x.vcd", "v.png"}},
  };
  Box::Options lim;
  lim.fsize_limit = 512;  // bytes: every output above is larger
  for (const auto& c : cases) {
    SCOPED_TRACE(c.kind);
    const Result r = box.run(c.args, lim);
    EXPECT_EQ(r.signal, 0) << "killed (SIGXFSZ must be ignored)\n" << r.describe();
    EXPECT_EQ(r.code, 1) << r.describe();
    const auto lines = lines_of(r.err);
    EXPECT_EQ(lines.size(), 1u) << r.describe();
    EXPECT_EQ(r.err.rfind("ropsim: error: " + c.must_not_exist[0] + ": ", 0), 0u) << r.describe();
    EXPECT_NE(r.err.find(std::strerror(EFBIG)), std::string::npos) << r.describe();
    for (const auto& f : c.must_not_exist) EXPECT_FALSE(fs::exists(box.path(f))) << f << " exists after the error";
    const auto left = box.leftovers();
    EXPECT_TRUE(left.empty()) << left[0];
  }
  // The same commands without the limit succeed (the limit is what failed).
  for (const auto& c : cases) {
    const Result r = box.run(c.args);
    EXPECT_EQ(r.code, 0) << r.describe();
    for (const auto& f : c.must_not_exist) EXPECT_TRUE(fs::exists(box.path(f))) << f;
  }
}

TEST(Output, KillDuringAWriteLeavesNoFileUnderTheFinalName) {
  Box box;
  const std::vector<std::string> args = {"scene", "cloth", "--width", "1920", "--height",
                                         "1080",  "--spp", "64",      "-o",   "big.trace"};
  for (int sig : {SIGKILL, SIGTERM}) {
    SCOPED_TRACE(sig == SIGKILL ? "SIGKILL" : "SIGTERM");
    const pid_t pid = box.start(args, "big");
    // Wait until the temporary file holds data, i.e. the writer has started.
    bool writing = false;
    const auto t0 = std::chrono::steady_clock::now();
    while (!writing && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(30)) {
      for (const auto& e : fs::directory_iterator(box.work()))
        if (e.path().filename().string().rfind(".big.trace.", 0) == 0 && fs::file_size(e.path()) > 0) writing = true;
      if (!writing) std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    ::kill(pid, sig);
    const Result r = box.wait(pid, "big", args);
    ASSERT_TRUE(writing) << "no temporary file with data appeared\n" << r.describe();
    EXPECT_EQ(r.signal, sig) << "ropsim finished before the signal: the test proves nothing\n" << r.describe();
    EXPECT_FALSE(fs::exists(box.path("big.trace"))) << "a partial trace under the final name";
    if (sig == SIGTERM) {  // a catchable signal also removes the temporary file
      const auto left = box.leftovers();
      EXPECT_TRUE(left.empty()) << left[0];
    }
    for (const auto& e : fs::directory_iterator(box.work())) fs::remove(e.path());
  }
}

TEST(Output, AFailedRunRemovesOnlyTheFilesItCreated) {
  Box box;
  std::ofstream(box.path("afile")) << "x";
  std::ofstream(box.path("keep.png")) << "old image";
  // The report cannot be written (its folder is a file): nothing is written,
  // and the image it was going to replace keeps its old contents.
  Result r = box.run(cat({"run", "--scene", "cloth", "--out", "keep.png", "--report", "afile/r.json"}, kSmall));
  EXPECT_EQ(r.code, 1) << r.describe();
  EXPECT_EQ(slurp(box.path("keep.png")), "old image");
  // A waveform this run created (committed by the cycle model before the
  // report failed) is removed; a pre-existing one is replaced, not deleted.
  const auto cyc =
      cat({"run", "--scene", "cloth", "--fidelity", "cycle", "--vcd", "new.vcd", "--report", "afile/r.json"},
          {"--width", "16", "--height", "16", "--spp", "4"});
  r = box.run(cyc);
  EXPECT_EQ(r.code, 1) << r.describe();
  EXPECT_FALSE(fs::exists(box.path("new.vcd"))) << "the failed run left the waveform it created";
  std::ofstream(box.path("old.vcd")) << "old";
  auto cyc2 = cyc;
  cyc2[6] = "old.vcd";
  r = box.run(cyc2);
  EXPECT_EQ(r.code, 1) << r.describe();
  EXPECT_TRUE(fs::exists(box.path("old.vcd"))) << "the failed run deleted a file it did not create";
  const auto left = box.leftovers();
  EXPECT_TRUE(left.empty()) << left[0];
}

// ------------------------------------------------------------ reproducible images

TEST(Output, ImagesAreByteReproducible) {
  Box box;
  const auto args = cat({"run", "--scene", "cloth", "--out", "a.exr", "--out", "a.png", "--quiet"}, kSmall);
  ASSERT_EQ(box.run(args).code, 0);
  const std::string exr = slurp(box.path("a.exr")), png = slurp(box.path("a.png"));
  // A wall-clock stamp has a resolution of one second: cross one.
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  ASSERT_EQ(box.run(args).code, 0);
  EXPECT_EQ(ropsim_test::first_byte_difference(exr, slurp(box.path("a.exr"))), "")
      << "two runs gave different EXR bytes (a timestamp in the metadata?)";
  EXPECT_EQ(ropsim_test::first_byte_difference(png, slurp(box.path("a.png"))), "")
      << "two runs gave different PNG bytes";
  EXPECT_EQ(exr.find("capDate\0string\0\x13", 0, 16), std::string::npos) << "the EXR has a capture date";
}

// ------------------------------------------------------------ exit statuses

/// Exactly one stderr line starting with prefix.
void expect_one_line(const Result& r, const std::string& prefix) {
  const auto lines = lines_of(r.err);
  EXPECT_EQ(lines.size(), 1u) << r.describe();
  EXPECT_EQ(r.err.rfind(prefix, 0), 0u) << r.describe();
}

TEST(ExitStatus, EveryRowOfTheReadmeTable) {
  Box box;
  std::ofstream(box.path("bad.trace"), std::ios::binary) << "RSTRACE1 but not really a trace";
  std::ofstream(box.path("afile")) << "x";
  // 0: success, --help, --version.
  Result r = box.run(cat({"run", "--scene", "cloth", "--report", "ok.json", "--quiet"}, kSmall));
  EXPECT_EQ(r.code, 0) << r.describe();
  r = box.run({"--help"});
  EXPECT_EQ(r.code, 0) << r.describe();
  r = box.run({"--version"});
  EXPECT_EQ(r.code, 0) << r.describe();
  EXPECT_NE(r.out.find("ropsim 0."), std::string::npos) << r.describe();
  EXPECT_NE(r.out.find("commit "), std::string::npos) << r.describe();
  // 1: user errors, one line each.
  const std::vector<std::pair<std::string, std::vector<std::string>>> user = {
      {"bad trace", {"run", "--trace", "bad.trace", "--report", "r.json"}},
      {"bad trace (validate)", {"trace", "validate", "bad.trace"}},
      {"bad config key", cat({"run", "--fidelity", "cycle", "--hw-set", "nosuch.key=1", "--report", "r.json"}, kSmall)},
      {"bad scene", {"run", "--scene", "nosuch", "--report", "r.json"}},
      {"bad scene (scene verb)", {"scene", "nosuch", "-o", "x.trace"}},
      {"bad flag", {"run", "--nosuch-flag"}},
      {"missing verb", {}},
      {"bad flag value", cat({"run", "--scene", "cloth", "--spp", "3"}, {})},
      {"unwritable output", cat({"run", "--scene", "cloth", "--report", "afile/r.json"}, kSmall)},
      {"output is a folder", cat({"run", "--scene", "cloth", "--report", "."}, kSmall)},
  };
  for (const auto& [what, args] : user) {
    SCOPED_TRACE(what);
    r = box.run(args);
    EXPECT_EQ(r.code, 1) << r.describe();
    expect_one_line(r, "ropsim: error: ");
  }
  EXPECT_FALSE(fs::exists(box.path("r.json")));
  // 2: an internal error (the test hook), one line naming it.
  Box::Options hook;
  hook.env = {"ROPSIM_TEST_INTERNAL_ERROR=1"};
  r = box.run({"config"}, hook);
  EXPECT_EQ(r.code, 2) << r.describe();
  expect_one_line(r, "ropsim: internal error: ");
  EXPECT_NE(r.err.find("please report it"), std::string::npos) << r.describe();
}

// ------------------------------------------------------------ the library, in process

TEST(OutputFile, UncommittedOutputLeavesNothingAndCommitReplaces) {
  Box box;
  const std::string p = box.path("t.txt");
  {
    ropsim::OutputFile f(p);
    f.write("partial");
  }
  EXPECT_FALSE(fs::exists(p));
  EXPECT_TRUE(box.leftovers().empty());
  std::ofstream(p) << "old";
  fs::permissions(p, fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
  ropsim::write_text_output(p, "new");
  EXPECT_EQ(slurp(p), "new");
  EXPECT_EQ(fs::status(p).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read)
      << "a replaced file keeps its permissions";
  EXPECT_THROW(ropsim::write_text_output(box.path("no/such/folder/x"), "x"), ropsim::UserError);
  EXPECT_THROW(ropsim::write_text_output("-", "x"), ropsim::UserError) << "'-' only where allowed";
  EXPECT_THROW(ropsim::write_text_output(box.work().string(), "x"), ropsim::UserError) << "a folder is not a target";
  EXPECT_TRUE(box.leftovers().empty());
}

TEST(OutputFile, ByNameAndThroughAPipeForLibraryWriters) {
  Box box;
  // The pipe's private folder goes to $TMPDIR: the box's, restored on any exit.
  struct TmpdirGuard {
    std::string old;
    bool had;
    explicit TmpdirGuard(const std::string& dir) : had(std::getenv("TMPDIR") != nullptr) {
      if (had) old = std::getenv("TMPDIR");
      ::setenv("TMPDIR", dir.c_str(), 1);
    }
    ~TmpdirGuard() { had ? (void)::setenv("TMPDIR", old.c_str(), 1) : (void)::unsetenv("TMPDIR"); }
  } guard(box.tmp().string());
  const auto write_by_name = [](const std::string& name, const std::string& text) {
    FILE* f = std::fopen(name.c_str(), "w");  // as SystemC or an image library would
    ASSERT_NE(f, nullptr) << name;
    std::fputs(text.c_str(), f);
    std::fclose(f);
  };
  for (bool pipe : {false, true}) {
    SCOPED_TRACE(pipe ? "via_pipe" : "named");
    ropsim::OutputFile::Options o;
    o.named = true;
    o.via_pipe = pipe;
    o.suffix = ".vcd";
    const std::string p = box.path(pipe ? "p.vcd" : "n.vcd");
    {
      ropsim::OutputFile f(p, o);
      EXPECT_EQ(f.write_name().substr(f.write_name().size() - 4), ".vcd");
      write_by_name(f.write_name(), "$enddefinitions $end\n#0\n");
      f.commit();
    }
    EXPECT_EQ(slurp(p), "$enddefinitions $end\n#0\n");
    {  // never opened by the library, then discarded: nothing left, no hang
      ropsim::OutputFile f(box.path("never.vcd"), o);
    }
    EXPECT_FALSE(fs::exists(box.path("never.vcd")));
    // In place: a FIFO target receives the bytes and stays a FIFO.
    const std::string fifo = box.path(pipe ? "pf" : "nf");
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    std::string got;
    std::thread reader([&] {
      std::ifstream in(fifo, std::ios::binary);
      std::ostringstream ss;
      ss << in.rdbuf();
      got = ss.str();
    });
    {
      ropsim::OutputFile f(fifo, o);
      EXPECT_TRUE(f.in_place());
      write_by_name(f.write_name(), "in place");
      f.commit();
    }
    reader.join();
    EXPECT_EQ(got, "in place");
    EXPECT_TRUE(is_fifo(fifo));
  }
  const auto left = box.leftovers();
  EXPECT_TRUE(left.empty()) << left[0];
}

TEST(OutputFile, OutputPlanComparesWhereNamesLead) {
  Box box;
  const std::string w = box.work().string();
  fs::create_directories(box.work() / "d");
  fs::create_symlink("d", box.path("dl"));  // a symlink to a folder
  std::ofstream(box.path("d/a")) << "a";
  auto clash = [](const std::vector<std::pair<std::string, std::string>>& outs) -> std::string {
    ropsim::OutputPlan plan;
    for (const auto& [what, path] : outs) plan.output(what, path);
    try {
      plan.check();
    } catch (const ropsim::UserError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(clash({{"--a", w + "/d/a"}, {"--b", w + "/dl/a"}}), "") << "through a folder's symlink";
  EXPECT_NE(clash({{"--a", w + "/d/new"}, {"--b", w + "/dl/../d/new"}}), "") << "a name that does not exist yet";
  EXPECT_EQ(clash({{"--a", w + "/d/a"}, {"--b", w + "/d/b"}}), "");
  EXPECT_EQ(clash({{"--a", "-"}, {"--b", "-"}}), "") << "standard output is not a file here";
  EXPECT_EQ(clash({{"--a", "/dev/null"}, {"--b", "/dev/null"}}), "") << "a character device takes several outputs";
  ropsim::OutputPlan in;
  in.input("--trace", w + "/d/a");
  in.input("--hw", w + "/d/a");  // two inputs may be one file
  in.output("--report", w + "/dl/a");
  try {
    in.check();
    ADD_FAILURE() << "an output that is an input was accepted";
  } catch (const ropsim::UserError& e) {
    EXPECT_NE(std::string(e.what()).find("the input --trace"), std::string::npos) << e.what();
  }
}

// ------------------------------------------------------------ distinct outputs

/// Every file and folder under work/ (relative), but those in keep.
std::vector<std::string> written_files(const Box& box, const std::vector<std::string>& keep) {
  std::vector<std::string> v;
  for (const auto& e : fs::recursive_directory_iterator(box.work())) {
    const std::string rel = fs::relative(e.path(), box.work()).string();
    if (std::find(keep.begin(), keep.end(), rel) == keep.end()) v.push_back(rel);
  }
  return v;
}

TEST(Output, TwoOutputsThatAreOneFileAreRefusedBeforeAnyWork) {
  Box box;
  ASSERT_EQ(box.run(cat({"scene", "testcard", "-o", "t.trace"}, kSmall)).code, 0);
  std::ofstream(box.path("h1.json")) << "old";
  ASSERT_EQ(::link(box.path("h1.json").c_str(), box.path("h2.json").c_str()), 0) << std::strerror(errno);
  fs::create_symlink("s.json", box.path("link.json"));  // dangling: s.json is written by the run
  fs::create_directories(box.work() / "sub");
  const std::vector<std::string> keep = {"t.trace", "h1.json", "h2.json", "link.json", "sub"};
  const std::vector<std::string> cycle = {"--fidelity", "cycle"};
  struct Case {
    std::vector<std::string> args;
    std::string first, second, path;  ///< the two flags and the path the line names
  };
  const std::vector<Case> cases = {
      {{"--out", "x.exr", "--report", "x.exr"}, "--out", "--report", "x.exr"},
      {{"--out", "x.png", "--report", "x.png"}, "--out", "--report", "x.png"},
      {{"--out", "x.png", "--out", "sub/../x.png"}, "--out", "--out", "x.png"},
      {{"--report", "x.json", "--draw-csv", "x.json"}, "--report", "--draw-csv", "x.json"},
      {cat(cycle, {"--vcd", "x.json", "--report", "x.json"}), "--report", "--vcd", "x.json"},
      {cat(cycle, {"--vcd", "x.vcd", "--stats-interval", "100", "--stats-csv", "x.vcd"}), "--vcd", "--stats-csv",
       "x.vcd"},
      {cat(cycle, {"--vcd", "x", "--report", "x.gtkw"}), "--report", "--vcd's GTKWave save file", "x.gtkw"},
      {{"--maps", "m", "--out", "m/fragments.png"}, "--out", "--maps", "m/fragments.png"},
      {{"--report", "s.json", "--draw-csv", "link.json"}, "--report", "--draw-csv", "link.json"},  // a symlink
      {{"--report", "h1.json", "--draw-csv", "h2.json"}, "--report", "--draw-csv", "h2.json"},     // a hard link
      {{"--report", "t.trace"}, "--report", "the input --trace", "t.trace"},                       // the input
  };
  for (const auto& c : cases) {
    const auto args = cat({"run", "--trace", "t.trace", "--quiet"}, c.args);
    std::string shown = "ropsim";
    for (const auto& a : args) shown += " " + a;
    SCOPED_TRACE(shown);
    const Result r = box.run(args);
    EXPECT_EQ(r.code, 1) << r.describe();
    EXPECT_EQ(lines_of(r.err).size(), 1u) << r.describe();
    EXPECT_EQ(r.err.rfind("ropsim: error: ", 0), 0u) << r.describe();
    for (const auto& w : {c.first, c.second, c.path})
      EXPECT_NE(r.err.find(w), std::string::npos) << "the line does not name " << w << "\n" << r.describe();
    EXPECT_EQ(written_files(box, keep), std::vector<std::string>{}) << "written before the refusal\n" << r.describe();
    EXPECT_EQ(slurp(box.path("h1.json")), "old");
    EXPECT_GT(fs::file_size(box.path("t.trace")), 100u) << "the input was replaced";
  }
  // The other verbs: an output that is the input.
  for (const auto& args : std::vector<std::vector<std::string>>{{"trace", "dump", "t.trace", "-o", "t.trace"},
                                                                {"livepoints", "t.trace", "-o", "./t.trace"}}) {
    const Result r = box.run(args);
    EXPECT_EQ(r.code, 1) << r.describe();
    EXPECT_EQ(lines_of(r.err).size(), 1u) << r.describe();
    EXPECT_NE(r.err.find("t.trace"), std::string::npos) << r.describe();
    EXPECT_EQ(trace_problem(box.path("t.trace")), "") << "the input was replaced";
  }
  // Distinct names for one run are fine (a control: the refusals are about the clash).
  const Result ok = box.run(
      cat({"run", "--trace", "t.trace", "--quiet", "--out", "x.png", "--report", "x.json", "--maps", "m"}, cycle));
  EXPECT_EQ(ok.code, 0) << ok.describe();
  EXPECT_TRUE(fs::exists(box.path("m/fragments.png")));
}

// ------------------------------------------------------------ readers that close, FIFOs without a reader

/// A reader of the FIFO at path that reads `limit` bytes, then closes it.
struct EarlyReader {
  std::string path;
  std::thread t;
  size_t got = 0;
  EarlyReader(const std::string& p, size_t limit) : path(p) {
    t = std::thread([this, limit] {
      const int fd = ::open(path.c_str(), O_RDONLY);
      if (fd < 0) return;
      (void)::fcntl(fd, F_SETPIPE_SZ, 4096);  // the smallest buffer: the writer soon meets the close
      char buf[256];
      while (got < limit) {
        const ssize_t n = ::read(fd, buf, std::min(sizeof buf, limit - got));
        if (n <= 0) break;
        got += size_t(n);
      }
      ::close(fd);
    });
  }
  ~EarlyReader() {
    // Unblock the open if the writer never came.
    const int fd = ::open(path.c_str(), O_WRONLY | O_NONBLOCK);
    if (fd >= 0) ::close(fd);
    t.join();
  }
};

TEST(Output, AReaderThatClosesEarlyIsAnErrorNotASignal) {
  Box box;
  ASSERT_EQ(box.run(cat({"scene", "testcard", "-o", "t.trace"}, {"--spp", "4"})).code, 0);
  struct Case {
    const char* what;
    std::vector<std::string> args;
    std::string fifo;
  };
  // Each output is far larger than a pipe's buffer (64 KiB).
  const std::vector<Case> cases = {
      {"vcd", {"run", "--fidelity", "cycle", "--trace", "t.trace", "--vcd", "v.vcd", "--quiet"}, "v.vcd"},
      // 512 x 512: about 130 KiB of EXR (the 4-spp testcard trace's is 22 KiB,
      // which the pipe's buffer could take whole before the reader closes).
      {"exr",
       {"run", "--scene", "testcard", "--spp", "4", "--width", "512", "--height", "512", "--out", "x.exr", "--quiet"},
       "x.exr"},
      {"trace dump", {"trace", "dump", "t.trace", "-o", "d.jsonl"}, "d.jsonl"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.what);
    ASSERT_EQ(::mkfifo(box.path(c.fifo).c_str(), 0600), 0) << std::strerror(errno);
    Result r;
    {
      EarlyReader reader(box.path(c.fifo), 100);
      r = box.run(c.args);
    }
    EXPECT_EQ(r.signal, 0) << "killed by a signal (SIGPIPE must be ignored)\n" << r.describe();
    EXPECT_EQ(r.code, 1) << r.describe();
    EXPECT_EQ(r.err, "ropsim: error: " + c.fifo + ": the reader closed it\n") << r.describe();
    EXPECT_TRUE(is_fifo(box.path(c.fifo)));
    EXPECT_FALSE(fs::exists(box.path("v.gtkw"))) << "the waveform's save file was written after the error";
    const auto left = box.leftovers();
    EXPECT_TRUE(left.empty()) << left[0];
    fs::remove(box.path(c.fifo));
  }
  // Standard output closed early: quiet, as any tool in a pipeline (the
  // status of a SIGPIPE), with no temporary file left.
  for (const auto& args : std::vector<std::vector<std::string>>{
           {"trace", "dump", "t.trace"},
           {"run", "--fidelity", "cycle", "--trace", "t.trace", "--report", "-", "--out", "y.png"}}) {
    int p[2];
    ASSERT_EQ(::pipe2(p, O_CLOEXEC), 0);  // the child keeps only the write end, as its stdout
    // One page of buffer: the output (more than 4 KiB) cannot all fit before the close.
    ASSERT_GE(::fcntl(p[1], F_SETPIPE_SZ, 4096), 4096) << std::strerror(errno);
    Box::Options o;
    o.stdout_fd = p[1];
    const pid_t pid = box.start(args, "pipe", o);
    ::close(p[1]);
    char buf[100];
    size_t got = 0;
    for (ssize_t n; got < sizeof buf && (n = ::read(p[0], buf + got, sizeof buf - got)) > 0;) got += size_t(n);
    ::close(p[0]);
    const Result r = box.wait(pid, "pipe", args);
    EXPECT_EQ(got, sizeof buf) << r.describe();
    EXPECT_EQ(r.signal, SIGPIPE) << r.describe();
    EXPECT_EQ(r.err, "") << r.describe();
    const auto left = box.leftovers();
    EXPECT_TRUE(left.empty()) << left[0];
  }
}

TEST(Output, AFifoWithoutAReaderWaitsSaysSoAndTimesOut) {
  Box box;
  const std::string fifo = box.path("r.json");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0) << std::strerror(errno);
  const auto args = cat({"run", "--scene", "cloth", "--report", "r.json", "--quiet"}, kSmall);
  // --output-timeout: one line naming the file and the flag, exit 1.
  for (const char* t : {"0", "0.05"}) {
    SCOPED_TRACE(std::string("--output-timeout ") + t);
    const Result r = box.run(cat({"--output-timeout", t}, args));
    EXPECT_EQ(r.code, 1) << r.describe();
    auto lines = lines_of(r.err);
    if (std::string(t) != "0") {  // it waited: it said so, once
      ASSERT_FALSE(lines.empty()) << r.describe();
      EXPECT_EQ(lines[0], "ropsim: waiting for a reader of r.json") << r.describe();
      lines.erase(lines.begin());
    }
    EXPECT_EQ(lines, std::vector<std::string>{"ropsim: error: r.json: no reader opened it within " + std::string(t) +
                                              " s (--output-timeout)"})
        << r.describe();
    EXPECT_TRUE(is_fifo(fifo));
  }
  // The default waits for a reader, saying so once; the report then arrives whole.
  const pid_t pid = box.start(args, "wait");
  const fs::path err = box.work().parent_path() / "io" / "wait.err";
  bool said = false;
  for (int i = 0; i < 60000 && !said; ++i) {  // up to a minute, for a loaded machine
    said = slurp(err).find("waiting for a reader of r.json") != std::string::npos;
    if (!said) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  std::string got;
  if (said) {
    std::ifstream in(fifo, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    got = ss.str();
  } else {
    ::kill(pid, SIGKILL);
  }
  const Result r = box.wait(pid, "wait", args);
  ASSERT_TRUE(said) << "no word while it waits\n" << r.describe();
  EXPECT_EQ(r.code, 0) << r.describe();
  EXPECT_EQ(r.err, "ropsim: waiting for a reader of r.json\n") << r.describe();
  EXPECT_EQ(json_problem(got), "") << got.substr(0, 300);
}

// ------------------------------------------------------------ default names

TEST(Output, DefaultNamesComeFromTheInputReplayed) {
  Box box;
  ASSERT_EQ(box.run(cat({"scene", "testcard", "-o", "motor.trace"}, kSmall)).code, 0);
  ASSERT_EQ(box.run({"livepoints", "motor.trace", "-o", "motor.rlp", "--quiet"}).code, 0);
  ASSERT_EQ(
      box.run(cat({"livepoints", "--scene", "eight-layers", "--method", "opaque", "-o", "e.rlp", "--quiet"}, kSmall))
          .code,
      0);
  /// The names under out/run/ after a run (removed for the next).
  auto names = [&](const std::vector<std::string>& args) {
    const Result r = box.run(cat(args, {"--quiet"}));
    EXPECT_EQ(r.code, 0) << r.describe();
    std::vector<std::string> v;
    if (fs::exists(box.work() / "out" / "run"))
      for (const auto& e : fs::directory_iterator(box.work() / "out" / "run")) v.push_back(e.path().filename());
    std::sort(v.begin(), v.end());
    fs::remove_all(box.work() / "out");
    return v;
  };
  auto expect_base = [](const std::vector<std::string>& got, const std::string& prefix) {
    ASSERT_EQ(got.size(), 3u) << "png, exr and json expected";
    for (const auto& n : got) EXPECT_EQ(n.rfind(prefix, 0), 0u) << n << " does not start with " << prefix;
  };
  // Sampled on a library: named after the library's input, spp and method
  // (not the default scene cloth at 16 spp).
  expect_base(names({"run", "--fidelity", "sampled", "--livepoints", "motor.rlp"}), "motor-lk-4spp-sampled-hw");
  expect_base(names({"run", "--fidelity", "sampled", "--livepoints", "e.rlp"}),
              "eight-layers-64x64-opaque-4spp-sampled-hw");
  // Every fidelity on a trace: its stem and its header's spp.
  expect_base(names({"run", "--trace", "motor.trace"}), "motor-lk-4spp.");
  for (const char* f : {"sampled", "cycle", "approximate"})
    expect_base(names({"run", "--trace", "motor.trace", "--fidelity", f}), std::string("motor-lk-4spp-") + f + "-hw");
  // A scene's parameters that change the input are in its name.
  expect_base(names(cat({"run", "--scene", "testcard", "--scene-seed", "3", "--repeat", "2"}, kSmall)),
              "testcard-64x64-seed3-lk-4spp-x2.");
}

// ------------------------------------------------------------ folders, modes, standard output, flags

TEST(Output, AFailedRunRemovesTheFoldersItCreated) {
  Box box;
  std::ofstream(box.path("afile")) << "x";
  // The report cannot be written: the maps folder and the image's missing
  // folders this run made go with the files.
  const Result r = box.run(cat({"run", "--scene", "cloth", "--maps", "m/deep", "--out", "nodir/sub/x.png", "--report",
                                "afile/r.json", "--quiet"},
                               kSmall));
  EXPECT_EQ(r.code, 1) << r.describe();
  EXPECT_EQ(written_files(box, {"afile"}), std::vector<std::string>{}) << r.describe();
  // The maps cannot be written (a full disk, here the file size limit).
  Box::Options lim;
  lim.fsize_limit = 512;
  const Result f =
      box.run(cat({"run", "--scene", "cloth", "--maps", "m2", "--report", "r.json", "--quiet"}, kSmall), lim);
  EXPECT_EQ(f.code, 1) << f.describe();
  EXPECT_EQ(written_files(box, {"afile"}), std::vector<std::string>{}) << f.describe();
  // A folder that was there stays, with what it held.
  fs::create_directories(box.work() / "m");
  std::ofstream(box.path("m/mine.txt")) << "keep";
  const Result r2 =
      box.run(cat({"run", "--scene", "cloth", "--maps", "m", "--report", "afile/r.json", "--quiet"}, kSmall));
  EXPECT_EQ(r2.code, 1) << r2.describe();
  EXPECT_EQ(written_files(box, {"afile", "m", "m/mine.txt"}), std::vector<std::string>{}) << r2.describe();
  // On success the missing folders are made (docs/outputs.md).
  const Result ok = box.run(cat({"run", "--scene", "cloth", "--out", "nodir/sub/x.png", "--quiet"}, kSmall));
  EXPECT_EQ(ok.code, 0) << ok.describe();
  EXPECT_EQ(image_problem(box.path("nodir/sub/x.png")), "");
}

TEST(Output, NewFilesGetTheUmasksModeAndReplacedFilesKeepTheirs) {
  Box box;
  Box::Options o;
  o.umask = 027;
  std::ofstream(box.path("old.json")) << "old";
  fs::permissions(box.path("old.json"), fs::perms(0604));
  const Result r =
      box.run(cat({"run", "--scene", "cloth", "--out", "new.png", "--report", "old.json", "--quiet"}, kSmall), o);
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_EQ(int(fs::status(box.path("new.png")).permissions() & fs::perms::all), 0640);
  EXPECT_EQ(int(fs::status(box.path("old.json")).permissions() & fs::perms::all), 0604);
  // The study report (written by analysis/study_report.py) alike.
  std::ofstream(box.path("s.toml")) << "[study]\nname = \"modes\"\n[inputs]\nscenes = [\"cloth\"]\n"
                                       "[axes]\nmethod = [\"lk\"]\nspp = [4]\nwidth = 16\nheight = 16\n";
  const Result run = box.run({"study", "run", "s.toml", "--out", "st", "-j", "1", "--quiet"}, o);
  ASSERT_EQ(run.code, 0) << run.describe();
  const Result rep = box.run({"study", "report", "st"}, o);
  ASSERT_EQ(rep.code, 0) << rep.describe();
  for (const char* f : {"st/report/index.html", "st/report/summary.md"})
    EXPECT_EQ(int(fs::status(box.path(f)).permissions() & fs::perms::all), 0640) << f;
  const Result exp = box.run({"study", "export", "st", "--csv", "st.csv"}, o);
  ASSERT_EQ(exp.code, 0) << exp.describe();
  EXPECT_EQ(int(fs::status(box.path("st.csv")).permissions() & fs::perms::all), 0640);
}

TEST(Output, AFailedWriteToStandardOutputIsAnError) {
  Box box;
  ASSERT_EQ(box.run(cat({"scene", "cloth", "-o", "s.trace"}, kSmall)).code, 0);
  Box::Options full;
  full.stdout_path = "/dev/full";
  for (const auto& args :
       std::vector<std::vector<std::string>>{{"scene", "--list"},
                                             {"config"},
                                             {"trace", "info", "s.trace"},
                                             {"trace", "dump", "s.trace"},
                                             {"--help"},
                                             cat({"run", "--scene", "cloth", "--report", "-"}, kSmall),
                                             cat({"run", "--scene", "cloth", "--out", "a.png"}, kSmall)}) {
    const Result r = box.run(args, full);
    EXPECT_EQ(r.code, 1) << r.describe();
    EXPECT_EQ(r.err, std::string("ropsim: error: standard output: ") + std::strerror(ENOSPC) + "\n") << r.describe();
  }
  EXPECT_FALSE(fs::exists(box.path("a.png"))) << "a run that failed kept the image it created";
}

TEST(ExitStatus, MemoryLimitZeroAndEmptyAreRefusedNoneIsNoLimit) {
  Box box;
  for (const char* v : {"0", "0M", ""}) {
    SCOPED_TRACE(std::string("--memory-limit '") + v + "'");
    const Result r = box.run({"--memory-limit", v, "config"});
    EXPECT_EQ(r.code, 1) << r.describe();
    expect_one_line(r, "ropsim: error: --memory-limit \"" + std::string(v) + "\": ");
  }
  const Result r = box.run(cat({"run", "--scene", "cloth", "--memory-limit", "none", "--report", "-"}, kSmall));
  EXPECT_EQ(r.code, 0) << r.describe();
  const auto j = nlohmann::json::parse(r.out, nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << r.out.substr(0, 300);
  EXPECT_EQ(j["host"]["memory_limit_bytes"], 0) << "none: no limit";
}

}  // namespace
