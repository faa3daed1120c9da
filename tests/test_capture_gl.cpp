// `ropsim capture gl` (docs/capture.md "Capturing a frame of an OpenGL
// application"), end to end: the command starts its own Xvfb and the
// application (or glretrace) with the capture library preloaded, and stops
// them again; nothing is left running.
//
//  - CaptureGlProcess.*: the command's process handling and its errors,
//    with a stand-in for the library (tests/gl/stand_in_capture_library.cpp:
//    it writes the status the real one would, or none). They need Xvfb only.
//  - CaptureGl.*: the real library (CMake target ropsim_glcapture) on
//    glmark2 and on the GL test programs of tests/gl/: the frame ropsim's
//    blend method makes from the trace against the frame the application
//    rendered, coverage against an independent count and against ropsim's own
//    rasterizer, discard, fixed function, API order, FBO targets, and a
//    capture made twice. A tree without the library's target skips them,
//    naming it; a tree with it runs them all.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "sim/image/image_io.h"
#include "tests/compare_util.h"
#include "tests/study_test_util.h"
#include "traces/capture/capture.h"
#include "traces/capture/scene_file.h"
#include "traces/format/trace.h"
#include "util/child_process.h"

#ifndef ROPSIM_BINARY
#error "ROPSIM_BINARY must name the built ropsim executable (tests/CMakeLists.txt)"
#endif
#ifndef ROPSIM_STAND_IN_CAPTURE_LIBRARY
#error "ROPSIM_STAND_IN_CAPTURE_LIBRARY must name the stand-in capture library (tests/CMakeLists.txt)"
#endif

namespace fs = std::filesystem;
using nlohmann::json;

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
  int code = -1;   ///< exit status, or -1 when killed by a signal
  int signal = 0;  ///< the signal that ended it
  std::string out, err;
  std::string describe() const {
    return "exit " + std::to_string(code) + (signal ? " signal " + std::to_string(signal) : "") + "\nstdout:\n" + out +
           "stderr:\n" + err;
  }
};

/// A working folder for ropsim (work/) and one for its stdout/stderr (io/).
class Sandbox {
 public:
  Sandbox() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() /
            ("ropsim-test-gl-" + std::to_string(::getpid()) + "-" + (info ? std::string(info->name()) : "x"));
    fs::remove_all(root_);
    fs::create_directories(root_ / "work");
    fs::create_directories(root_ / "io");
  }
  ~Sandbox() {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }
  fs::path work() const { return root_ / "work"; }
  std::string path(const std::string& f) const { return (work() / f).string(); }

  /// Runs `env ENV ropsim ARGS` in work/ through /bin/sh.
  Result run(const std::string& args, const std::string& env = "") const {
    const fs::path out = root_ / "io" / "stdout", err = root_ / "io" / "stderr";
    const std::string cmd = "cd '" + work().string() + "' && env " + env + " '" ROPSIM_BINARY "' " + args + " >'" +
                            out.string() + "' 2>'" + err.string() + "' </dev/null";
    const int st = std::system(cmd.c_str());
    Result r;
    if (st != -1 && WIFEXITED(st)) r.code = WEXITSTATUS(st);
    r.out = slurp(out);
    r.err = slurp(err);
    return r;
  }

  std::set<std::string> files() const {
    std::set<std::string> s;
    for (const auto& e : fs::recursive_directory_iterator(work())) s.insert(fs::relative(e.path(), work()).string());
    return s;
  }

 private:
  fs::path root_;
};

std::string stand_in(const std::string& mode, const std::string& more = "") {
  return "ROPSIM_GLCAPTURE_LIB='" ROPSIM_STAND_IN_CAPTURE_LIBRARY "' ROPSIM_TEST_STAND_IN=" + mode + " " + more;
}

/// Fails with one stderr line "ropsim: error: ..." holding every needle, exit
/// status 1, and no new file in the working folder but those in `allowed`.
void expect_error(const Sandbox& box, const std::string& args, const std::string& env,
                  const std::vector<std::string>& needles, const std::set<std::string>& allowed = {}) {
  SCOPED_TRACE("ropsim " + args);
  const auto before = box.files();
  const Result r = box.run(args, env);
  EXPECT_EQ(r.code, 1) << r.describe();
  const auto lines = lines_of(r.err);
  ASSERT_EQ(lines.size(), 1u) << "stderr must be exactly one line\n" << r.describe();
  EXPECT_EQ(lines[0].rfind("ropsim: error: ", 0), 0u) << r.describe();
  for (const auto& n : needles)
    EXPECT_NE(lines[0].find(n), std::string::npos) << "the error does not mention \"" << n << "\"\n" << r.describe();
  for (const auto& f : box.files())
    if (!before.count(f) && !allowed.count(f.substr(0, f.find('/'))))
      ADD_FAILURE() << "a failed capture left " << f << " behind\n" << r.describe();
}

/// True once process pid has ended: it no longer exists, or it is a zombie
/// (a killed grandchild is reaped by init, not by ropsim, and a container's
/// init may never reap it). Polled up to 3 s.
bool gone(long pid) {
  for (int i = 0; i < 300; ++i) {
    if (::kill(pid_t(pid), 0) != 0 && errno == ESRCH) return true;
    std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
    std::string line;
    std::getline(stat, line);
    const size_t paren = line.rfind(')');
    if (paren != std::string::npos && paren + 2 < line.size() && line[paren + 2] == 'Z') return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

/// Every process the stand-in was loaded into and the Xvfb it saw have ended.
void expect_nothing_left(const fs::path& control) {
  const std::string pids = slurp(control / "pids");
  ASSERT_FALSE(pids.empty()) << "the stand-in library was not loaded: " << control / "pids"
                             << " is empty";
  for (const auto& l : lines_of(pids)) EXPECT_TRUE(gone(std::stol(l))) << "process " << l << " is still running";
  const std::string xvfb = slurp(control / "xvfb.pid");
  ASSERT_FALSE(xvfb.empty()) << "the stand-in found no Xvfb started by ropsim";
  EXPECT_TRUE(gone(std::stol(xvfb))) << "Xvfb (pid " << xvfb << ") is still running";
}

// ------------------------------------------------------------------ process handling (stand-in library)

// A capture runs the application on a display of its own, with the library
// preloaded and the environment of the library <-> command interface, copies
// the trace to -o, names every draw it did not capture, and stops Xvfb.
TEST(CaptureGlProcess, RunsTheApplicationWithTheLibraryAndItsEnvironment) {
  Sandbox box;
  const Result r = box.run("capture gl --frame 3 --spp 4 --target fbo:2 --keep-control k -o out/t.trace -- /bin/true",
                           stand_in("ok"));
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_EQ(slurp(box.path("out/t.trace")), "stand-in trace\n") << "the trace the library wrote, copied to -o";
  const std::string env = slurp(box.path("k/env.txt"));
  for (const char* v : {"ROPSIM_GL_FRAME=3\n", "ROPSIM_GL_SPP=4\n", "ROPSIM_GL_TARGET=fbo:2\n",
                        "LIBGL_ALWAYS_SOFTWARE=1\n", "GALLIUM_DRIVER=llvmpipe\n", "DISPLAY=:"})
    EXPECT_NE(env.find(v), std::string::npos) << "the application's environment lacks " << v << "\n" << env;
  EXPECT_EQ(env.find("ROPSIM_GL_LIST_ONLY"), std::string::npos) << env;
  EXPECT_EQ(env.find("ROPSIM_GL_COUNT_SAMPLES"), std::string::npos) << env;
  for (const char* s : {"wrote out/t.trace", "15 bytes", "frame 3", "fbo 2 32x16", "4 spp", "1 draw, 10 fragments",
                        "1 not captured", "draw 1 (program 0): fog mode GL_EXP2 is not emulated"})
    EXPECT_NE(r.out.find(s), std::string::npos) << "the summary lacks \"" << s << "\"\n" << r.describe();
  EXPECT_NE(r.err.find("ropsim: warning: /bin/true: draw 1 (program 0) is not in the trace: fog mode GL_EXP2"),
            std::string::npos)
      << r.describe();
  expect_nothing_left(box.work() / "k");
  const Result q = box.run("capture gl --frame 0 --quiet -o q.trace -- /bin/true", stand_in("ok"));
  EXPECT_EQ(q.code, 0) << q.describe();
  EXPECT_EQ(q.out, "") << "--quiet prints nothing on stdout";
  EXPECT_NE(q.err.find("not in the trace"), std::string::npos) << "--quiet keeps the warning\n" << q.describe();
  const auto left = box.files();
  EXPECT_EQ(left, (std::set<std::string>{"k", "k/env.txt", "k/pids", "k/xvfb.pid", "k/status.json", "k/list.json",
                                         "k/application.log", "k/xvfb.log", "k/capture.trace", "out", "out/t.trace",
                                         "q.trace"}))
      << "only -o and --keep-control's folder; the private folder of the second run is removed";
}

TEST(CaptureGlProcess, ListPrintsTheFramebuffersAndDrawsAndWritesNoTrace) {
  Sandbox box;
  const Result r = box.run("capture gl --frame 1 --list --count-samples --keep-control k -- /bin/true", stand_in("ok"));
  ASSERT_EQ(r.code, 0) << r.describe();
  const std::string env = slurp(box.path("k/env.txt"));
  EXPECT_NE(env.find("ROPSIM_GL_LIST_ONLY=1\n"), std::string::npos) << env;
  EXPECT_NE(env.find("ROPSIM_GL_COUNT_SAMPLES=1\n"), std::string::npos) << env;
  EXPECT_EQ(env.find("ROPSIM_GL_OUT"), std::string::npos) << "--list: no trace asked for\n" << env;
  const auto lines = lines_of(r.out);
  ASSERT_GE(lines.size(), 6u) << r.describe();
  EXPECT_EQ(lines[0], "frame 1 of /bin/true: 1 framebuffer");
  for (const char* s : {"presented", "32x16", "unorm8", "yes", "glass", "src-over",
                        "add(src_alpha, one_minus_src_alpha)", "less, no writes", "2 draws"})
    EXPECT_NE(r.out.find(s), std::string::npos) << "the list lacks \"" << s << "\"\n" << r.out;
  // The draw rows: index, framebuffer, program, name, kind, ..., fragments, covered, passed ("-": not counted).
  bool row0 = false, row1 = false;
  for (const auto& l : lines) {
    std::istringstream in(l);
    std::vector<std::string> w;
    for (std::string x; in >> x;) w.push_back(x);
    if (w.size() > 4 && w[0] == "0" && w[1] == "presented") row0 = w[2] == "3" && w[3] == "glass" && w.back() == "-";
    if (w.size() > 4 && w[0] == "1" && w[1] == "presented") row1 = w[2] == "0" && w.back() == "7";
  }
  EXPECT_TRUE(row0 && row1) << r.out;
  const Result j = box.run("capture gl --frame 1 --list --json -- /bin/true", stand_in("ok"));
  ASSERT_EQ(j.code, 0) << j.describe();
  EXPECT_EQ(json::parse(j.out), json::parse(slurp(box.path("k/list.json")))) << "--json prints list.json as it is";
  EXPECT_EQ(box.files().count("k/capture.trace"), 0u);
}

TEST(CaptureGlProcess, BadFlagsAreOneLineErrors) {
  Sandbox box;
  const std::string env = stand_in("ok");
  expect_error(box, "capture gl -o t.trace -- /bin/true", env, {"--frame"});
  expect_error(box, "capture gl --frame 1 --target fbo:x -o t.trace -- /bin/true", env, {"fbo:x"});
  expect_error(box, "capture gl --frame 1 --target fbo:0 -o t.trace -- /bin/true", env, {"fbo:0"});
  expect_error(box, "capture gl --frame 1 --spp 3 -o t.trace -- /bin/true", env, {"--spp"});
  expect_error(box, "capture gl --frame 1 -o t.trace", env, {"after --", "--apitrace"});
  expect_error(box, "capture gl --frame 1 --apitrace a.trace -o t.trace -- /bin/true", env, {"not both"});
  expect_error(box, "capture gl --frame 1 --list -o t.trace -- /bin/true", env, {"--list", "-o"});
  expect_error(box, "capture gl --frame 1 -- /bin/true", env, {"-o TRACE"});
  expect_error(box, "capture gl --frame 1 --reference-msaa -o t.trace -- /bin/true", env, {"--keep-control"});
  expect_error(box, "capture -o t.trace", env, {"SCENE", "capture gl"});
}

// The application is looked for before anything starts: the error names it
// (here with no Xvfb on PATH either: the application's error comes first).
TEST(CaptureGlProcess, AnApplicationNotFoundIsNamed) {
  Sandbox box;
  expect_error(box, "capture gl --frame 0 -o t.trace -- no-such-application-1f3 --flag", stand_in("ok"),
               {"no-such-application-1f3", "application not found", "PATH"});
  expect_error(box, "capture gl --frame 0 -o t.trace -- ./missing/app", stand_in("ok", "PATH=/nonexistent"),
               {"./missing/app", "application not found"});
  std::ofstream(box.path("not-executable")) << "#!/bin/sh\n";
  fs::permissions(box.path("not-executable"), fs::perms::owner_read | fs::perms::owner_write);
  expect_error(box, "capture gl --frame 0 -o t.trace -- ./not-executable", stand_in("ok"),
               {"./not-executable", "application not found"});
}

// Each missing piece names what to install (scripts/deps.sh).
TEST(CaptureGlProcess, MissingPackagesSayWhatToInstall) {
  Sandbox box;
  expect_error(box, "capture gl --frame 0 -o t.trace -- /bin/true", stand_in("ok", "PATH=/nonexistent"),
               {"Xvfb not found", "xvfb", "scripts/deps.sh"});
  std::ofstream(box.path("a.trace")) << "x";
  expect_error(box, "capture gl --frame 0 --apitrace a.trace -o t.trace", stand_in("ok", "PATH=/nonexistent"),
               {"glretrace not found", "apitrace", "scripts/deps.sh"});
  expect_error(box, "capture gl --frame 0 -o t.trace -- /bin/true", "ROPSIM_GLCAPTURE_LIB=/nonexistent/lib.so",
               {"ROPSIM_GLCAPTURE_LIB=/nonexistent/lib.so", "no such library file"});
  // A ropsim with no library beside it (a copy of the executable elsewhere).
  fs::create_directories(box.work() / "bin");
  fs::copy_file(ROPSIM_BINARY, box.work() / "bin" / "ropsim");
  const std::string moved = (box.work() / "bin" / "ropsim").string();
  const std::string cmd = "cd '" + box.work().string() + "' && env -u ROPSIM_GLCAPTURE_LIB '" + moved +
                          "' capture gl --frame 0 -o t.trace -- /bin/true 2>err.txt";
  const int st = std::system(cmd.c_str());
  EXPECT_TRUE(WIFEXITED(st) && WEXITSTATUS(st) == 1) << slurp(box.path("err.txt"));
  EXPECT_NE(slurp(box.path("err.txt")).find("libropsim_glcapture.so is not beside ropsim"), std::string::npos)
      << slurp(box.path("err.txt"));
  EXPECT_NE(slurp(box.path("err.txt")).find("ropsim_glcapture"), std::string::npos);
  EXPECT_FALSE(fs::exists(box.path("t.trace")));
}

// An application that ends before frame N: the library's status says so; with
// no status (a crash, an exit the library did not see), its exit status or
// signal is named. Exit 1, no trace, and nothing left running.
TEST(CaptureGlProcess, AnApplicationThatEndsBeforeTheFrameIsAnError) {
  Sandbox box;
  expect_error(box, "capture gl --frame 5 --keep-control k1 -o t.trace -- /bin/true", stand_in("exit-early"),
               {"/bin/true", "the application exited after 0 frames, before frame 5"}, {"k1"});
  expect_nothing_left(box.work() / "k1");
  expect_error(box, "capture gl --frame 5 --keep-control k2 -o t.trace -- /bin/sh -c 'echo bye >&2; exit 3'",
               stand_in("silent"), {"/bin/sh", "exited with status 3", "before the end of frame 5", "bye"}, {"k2"});
  expect_nothing_left(box.work() / "k2");
  expect_error(box, "capture gl --frame 5 --keep-control k3 -o t.trace -- /bin/sh -c 'kill -SEGV $$'",
               stand_in("silent"), {"/bin/sh", "was killed by signal 11", "before the end of frame 5"}, {"k3"});
  expect_nothing_left(box.work() / "k3");
}

// The library's error (a shader it cannot instrument names its program) is the
// command's one line.
TEST(CaptureGlProcess, TheLibrarysErrorIsTheCommandsError) {
  Sandbox box;
  expect_error(box, "capture gl --frame 2 -o t.trace -- /bin/true",
               stand_in("error", "ROPSIM_TEST_STAND_IN_ERROR='program 7: cannot instrument: writes gl_SampleMask'"),
               {"/bin/true: program 7: cannot instrument: writes gl_SampleMask"});
}

// An application that hangs is stopped after --timeout with everything it
// started (its process group), and so is Xvfb.
TEST(CaptureGlProcess, AHangIsStoppedAfterTheTimeout) {
  Sandbox box;
  expect_error(box, "capture gl --frame 0 --timeout 1 --keep-control k -o t.trace -- /bin/sh -c 'sleep 60 & sleep 60'",
               stand_in("silent"), {"/bin/sh", "frame 0 did not end within 1 s", "--timeout", "process group"}, {"k"});
  const auto pids = lines_of(slurp(box.path("k/pids")));
  EXPECT_GE(pids.size(), 3u) << "sh and its two sleeps each loaded the stand-in";
  expect_nothing_left(box.work() / "k");
}

// Ctrl-C or SIGTERM: ropsim stops its children, removes its private folder
// and its partial output, and dies of the signal.
TEST(CaptureGlProcess, ASignalStopsEveryChildAndEndsRopsimByIt) {
  for (int sig : {SIGINT, SIGTERM}) {
    SCOPED_TRACE(::strsignal(sig));
    Sandbox box;
    ropsim::ChildProcess::Spec spec;
    spec.argv = {ROPSIM_BINARY, "capture",           "gl", "--frame",    "0", "--keep-control", box.path("k"),
                 "-o",          box.path("t.trace"), "--", "/bin/sleep", "60"};
    spec.env = ropsim::environment_with(
        {{"ROPSIM_GLCAPTURE_LIB", ROPSIM_STAND_IN_CAPTURE_LIBRARY}, {"ROPSIM_TEST_STAND_IN", "silent"}});
    spec.output = box.path("ropsim.log");
    ropsim::ChildProcess ropsim(spec);
    // The application is running once the stand-in wrote its pid.
    for (int i = 0; i < 2000 && slurp(box.path("k/pids")).empty(); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    ASSERT_FALSE(slurp(box.path("k/pids")).empty()) << "the application did not start\n"
                                                    << slurp(box.path("ropsim.log"));
    ::kill(ropsim.pid(), sig);
    const auto e = ropsim.wait_until(std::chrono::steady_clock::now() + std::chrono::seconds(20), nullptr);
    ASSERT_TRUE(e.has_value()) << "ropsim did not end after the signal";
    EXPECT_TRUE(e->signaled && e->signal == sig) << "ropsim " << e->describe() << "\n" << slurp(box.path("ropsim.log"));
    expect_nothing_left(box.work() / "k");
    EXPECT_FALSE(fs::exists(box.path("t.trace")));
  }
}

#ifdef ROPSIM_GL_TEST_PROGRAMS
std::string gl_program(const std::string& name) { return std::string(ROPSIM_GL_TEST_PROGRAMS) + "/" + name; }

/// An apitrace trace of gl_order (3 frames), recorded under a display of its own.
std::string record_apitrace(const Sandbox& box) {
  const std::string apitrace = ropsim::find_executable("apitrace");
  if (apitrace.empty()) {
    ADD_FAILURE() << "apitrace not found: install apitrace (scripts/deps.sh)";
    return "";
  }
  ropsim::VirtualDisplay display(ropsim::find_executable("Xvfb"), 128, 128, box.path("xvfb-record.log"),
                                 std::chrono::seconds(20), nullptr);
  ropsim::ChildProcess::Spec spec;
  spec.argv = {apitrace, "trace", "-o", box.path("order.trace"), gl_program("gl_order"), "--frames", "3"};
  spec.env = ropsim::environment_with({{"DISPLAY", display.display()}, {"LIBGL_ALWAYS_SOFTWARE", "1"}});
  spec.output = box.path("record.log");
  ropsim::ChildProcess rec(spec);
  const auto e = rec.wait_until(std::chrono::steady_clock::now() + std::chrono::seconds(60), nullptr);
  EXPECT_TRUE(e && e->success()) << "apitrace trace failed: " << slurp(box.path("record.log"));
  fs::remove(box.path("xvfb-record.log"));
  fs::remove(box.path("record.log"));
  return "order.trace";
}

// glretrace replays the trace: a frame past its end is refused before
// anything starts; a frame inside it is captured (by the stand-in here).
TEST(CaptureGlProcess, ApitraceReplayCountsTheTracesFrames) {
  Sandbox box;
  const std::string t = record_apitrace(box);
  ASSERT_FALSE(t.empty());
  expect_error(box, "capture gl --apitrace " + t + " --frame 3 -o t.rop", stand_in("ok"),
               {t, "--frame 3 is past the end of the trace (3 frames, 0..2)"});
  const Result r = box.run("capture gl --apitrace " + t + " --frame 2 --keep-control k -o t.rop", stand_in("ok"));
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_NE(r.out.find("frame 2 of " + t), std::string::npos) << r.describe();
  expect_nothing_left(box.work() / "k");
  expect_error(box, "capture gl --apitrace " + t + " --frame 1 -o " + t, stand_in("ok"), {"-o", "--apitrace", t});
  std::ofstream(box.path("junk.trace")) << "not a trace";
  expect_error(box, "capture gl --apitrace junk.trace --frame 0 -o t2.rop", stand_in("ok"),
               {"junk.trace", "not an apitrace trace"});
  expect_error(box, "capture gl --apitrace missing.trace --frame 0 -o t2.rop", stand_in("ok"),
               {"missing.trace", "cannot open"});
}
#else
TEST(CaptureGlProcess, ApitraceReplayCountsTheTracesFrames) {
  FAIL() << "the GL test programs (tests/gl/) are not built: install libgl-dev libglx-dev libx11-dev "
            "(scripts/deps.sh) and configure again";
}
#endif

// ------------------------------------------------------------------ the real library

// Skipped only in a tree without the library's target; with it, a missing
// piece (the GL test programs, glmark2, the blend method) fails, naming it.
#if defined(ROPSIM_GLCAPTURE_LIBRARY) && defined(ROPSIM_GL_TEST_PROGRAMS)
#define ROPSIM_NEEDS_LIBRARY() (void)0
const std::string kLib = "ROPSIM_GLCAPTURE_LIB='" ROPSIM_GLCAPTURE_LIBRARY "' ";
#elif defined(ROPSIM_GLCAPTURE_LIBRARY)
#define ROPSIM_NEEDS_LIBRARY()                                                                         \
  FAIL() << "the GL test programs (tests/gl/) are not built: install libgl-dev libglx-dev libx11-dev " \
            "(scripts/deps.sh) and configure again"
const std::string kLib;
std::string gl_program(const std::string& name) { return name; }
#else
#if defined(ROPSIM_SANITIZED_BUILD)
#define ROPSIM_NEEDS_LIBRARY()                                                                           \
  GTEST_SKIP() << "the sanitizer build has no capture library (it is preloaded into applications built " \
                  "without the sanitizers); the normal build runs this test"
#else
#define ROPSIM_NEEDS_LIBRARY() \
  GTEST_SKIP() << "needs the capture library libropsim_glcapture.so (CMake target ropsim_glcapture), not in this tree"
#endif
const std::string kLib;
#ifndef ROPSIM_GL_TEST_PROGRAMS
std::string gl_program(const std::string& name) { return name; }
#endif
#endif

/// Every fragment of a trace, in trace order.
struct Captured {
  ropsim::TraceHeader header;
  std::vector<ropsim::Fragment> fragments;
};

Captured read_trace(const std::string& path) {
  ropsim::TraceReader r(path);
  Captured c;
  c.header = r.header();
  for (ropsim::Fragment f; r.next(f);) c.fragments.push_back(f);
  return c;
}

/// The frame the application rendered (the library's frame.rgba + frame.json),
/// rows top-down, RGB in [0, 255].
struct Frame {
  uint32_t width = 0, height = 0;
  std::vector<uint8_t> rgba;  ///< top-down
  const uint8_t* at(uint32_t x, uint32_t y) const { return &rgba[(size_t(y) * width + x) * 4]; }
};

Frame read_frame(const fs::path& control, const char* name) {
  const json j = json::parse(slurp(control / "frame.json"));
  Frame f;
  f.width = j.at("width").get<uint32_t>();
  f.height = j.at("height").get<uint32_t>();
  const std::string bytes = slurp(control / name);
  EXPECT_EQ(bytes.size(), size_t(f.width) * f.height * 4) << control / name;
  f.rgba.assign(bytes.begin(), bytes.end());
  f.rgba.resize(size_t(f.width) * f.height * 4);
  const std::string order = j.value("row_order", j.value("rows", std::string("bottom-up")));
  if (order.find("bottom") != std::string::npos)
    for (uint32_t y = 0; y < f.height / 2; ++y)
      std::swap_ranges(f.rgba.begin() + std::ptrdiff_t(size_t(y) * f.width * 4),
                       f.rgba.begin() + std::ptrdiff_t(size_t(y + 1) * f.width * 4),
                       f.rgba.begin() + std::ptrdiff_t(size_t(f.height - 1 - y) * f.width * 4));
  return f;
}

/// The share of pixels (those `only` keeps, every pixel without it) whose
/// bytes in ropsim's PNG are within 1 of the frame's in every channel.
double share_within_one_code(const ropsim::Image& img, const Frame& f, std::string* worst,
                             const std::vector<bool>* only = nullptr) {
  uint64_t ok = 0, n = 0;
  double worst_d = 0;
  for (uint32_t y = 0; y < f.height; ++y)
    for (uint32_t x = 0; x < f.width; ++x) {
      if (only && !(*only)[size_t(y) * f.width + x]) continue;
      const float* c = img.at(x, y);
      const uint8_t* g = f.at(x, y);
      double d = 0;
      // The image is the PNG's linear light; its bytes are what the screen shows.
      for (int k = 0; k < 3; ++k)
        d = std::max(d, std::abs(std::round(double(ropsim::linear_to_srgb(c[k])) * 255.0) - double(g[k])));
      ok += d <= 1.0 + 1e-6;
      ++n;
      if (d > worst_d) {
        worst_d = d;
        *worst = "pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") off by " + std::to_string(d) + " codes";
      }
    }
  return n ? double(ok) / double(n) : 0.0;
}

uint64_t popcount(uint64_t m) { return uint64_t(__builtin_popcountll(m)); }

// glmark2's jellyfish (SRC_ALPHA, ONE_MINUS_SRC_ALPHA) and pulsar
// (glBlendFuncSeparate) at 128 x 128: ropsim's blend method on the trace
// reproduces the frame the application rendered, at 1 spp against
// frame.rgba for >= 99.9 % of the pixels within 1/255 in every channel, and
// at 4 spp against the 4x MSAA reference for >= 99.9 % of the pixels that
// every fragment covers whole and >= 99 % of all pixels (jellyfish's perspective
// texture coordinates at its partly covered pixels fail this when an input
// is read at the pixel centre by llvmpipe's interpolateAtOffset); and
// each draw's covered samples in the trace equal its occlusion query's
// samples passed.
TEST(CaptureGl, Glmark2FramesAreReproducedByTheBlendMethod) {
  ROPSIM_NEEDS_LIBRARY();
  ASSERT_FALSE(ropsim::find_executable("glmark2").empty())
      << "glmark2 not found: install glmark2-x11 (scripts/deps.sh)";
  Sandbox box;
  for (const char* scene : {"jellyfish", "pulsar"})
    for (int spp : {1, 4}) {
      const std::string tag = std::string(scene) + std::to_string(spp);
      SCOPED_TRACE(tag);
      const std::string flags = "--frame 3 --spp " + std::to_string(spp) +
                                " --width 128 --height 128 --count-samples --keep-control k" + tag +
                                (spp == 4 ? " --reference-msaa" : "");
      const Result c = box.run(
          "capture gl " + flags + " -o " + tag + ".trace -- glmark2 --size 128x128 -b " + scene + ":duration=0.5",
          kLib);
      ASSERT_EQ(c.code, 0) << c.describe();
      // Covered samples per draw: the trace, the list, the occlusion query.
      const Captured t = read_trace(box.path(tag + ".trace"));
      std::map<uint32_t, uint64_t> covered;
      for (const auto& fr : t.fragments) covered[fr.draw_id] += popcount(fr.coverage);
      const json list = json::parse(slurp(box.work() / ("k" + tag) / "list.json"));
      uint32_t in_target = 0;
      for (const auto& d : list.at("draws")) {  // the trace's draw ids are the list's trace_draw
        if (d.at("framebuffer") != "presented") continue;
        ASSERT_TRUE(d.at("trace_draw").is_number()) << d.dump();
        const uint32_t id = d.at("trace_draw").get<uint32_t>();
        ASSERT_TRUE(d.at("samples_passed").is_number()) << d.dump();
        EXPECT_EQ(d.at("covered_samples").get<uint64_t>(), d.at("samples_passed").get<uint64_t>()) << d.dump();
        EXPECT_EQ(covered[id], d.at("covered_samples").get<uint64_t>()) << "trace draw " << id;
        ++in_target;
      }
      EXPECT_GT(in_target, 0u) << list.dump();
      const Result run = box.run("run --trace " + tag + ".trace --method blend --quiet -o " + tag + ".exr");
      if (run.code != 0) {  // e.g. a tree without the blend method: the coverage checks above still ran
        ADD_FAILURE() << run.describe();
        continue;
      }
      const ropsim::Image img = ropsim::read_image(box.path(tag + ".exr"));
      const Frame f = read_frame(box.work() / ("k" + tag), spp == 1 ? "frame.rgba" : "frame-msaa4.rgba");
      ASSERT_EQ(img.width, f.width);
      ASSERT_EQ(img.height, f.height);
      std::string worst;
      if (spp == 1) {
        EXPECT_GE(share_within_one_code(img, f, &worst), 0.999) << "worst: " << worst;
        continue;
      }
      std::vector<bool> whole(size_t(f.width) * f.height, true);  // every fragment there covers every sample
      const uint64_t all = (uint64_t{1} << spp) - 1;
      for (const auto& fr : t.fragments)
        if (fr.coverage != all) whole[size_t(fr.y) * f.width + fr.x] = false;
      const size_t kept = size_t(std::count(whole.begin(), whole.end(), true));
      EXPECT_GE(kept, whole.size() / 2) << "most pixels are whole";
      EXPECT_GE(share_within_one_code(img, f, &worst, &whole), 0.999)
          << "worst: " << worst << " (of the " << kept << " pixels whole)";
      std::string any;
      const double share = share_within_one_code(img, f, &any);
      std::cout << tag << ": " << share * 100 << " % of all pixels within one code of the MSAA reference\n";
      // Over all pixels the reference itself varies from run to run at
      // partly covered pixels (pulsar: 99.22 % to 99.99 % of them within one
      // code in six runs of the same build; cause not found): 99 % here, the
      // whole pixels held to 99.9 % above.
      EXPECT_GE(share, 0.99) << "of all pixels; worst: " << any;
    }
}

/// The clip-space triangles of a scene, as ropsim's capture prepares them,
/// in the file gl_mesh reads.
void write_vertices(const ropsim::PreparedScene& ps, const std::string& path) {
  std::ofstream f(path, std::ios::binary);
  uint32_t n = 0;
  for (const auto& d : ps.draws) n += uint32_t(d.triangles.size());
  f.write(reinterpret_cast<const char*>(&n), 4);
  for (const auto& d : ps.draws)
    for (const auto& t : d.triangles)
      for (const auto& v : t.v) f.write(reinterpret_cast<const char*>(v.pos.data()), 16);
}

/// (prim, x, y) -> coverage of draw 0.
std::map<std::tuple<uint32_t, uint32_t, uint32_t>, uint64_t> coverage_of(const Captured& c) {
  std::map<std::tuple<uint32_t, uint32_t, uint32_t>, uint64_t> m;
  for (const auto& f : c.fragments) m[{f.prim_id, f.x, f.y}] |= f.coverage;
  return m;
}

// The cloth mesh at 64 x 64, drawn by gl_mesh through Mesa and captured by
// ropsim capture gl, against `ropsim capture` of the same scene: at 16 and 64
// spp, >= 99.9 % of the samples either covers (per primitive and pixel) agree.
// glmark2's build scene draws one opaque model (blending off, depth test
// LESS, writing): without src-over draws, every per-sample method and the
// A-buffer reference must write blend's PNG byte for byte (docs/methods.md
// "Methods on a frame of draw states"), lk's opaque draw bypasses its tracker
// and the report counts the draw's fragments as opaque; wboit, lk+ac,
// lk+depth and lk+depth+ac draw it in their pre-pass and composite nothing
// over it, so their PNG is blend's too.
TEST(CaptureGl, AnOpaqueFrameIsBlendsFrameForEveryPerSampleMethod) {
  ROPSIM_NEEDS_LIBRARY();
  ASSERT_FALSE(ropsim::find_executable("glmark2").empty())
      << "glmark2 not found: install glmark2-x11 (scripts/deps.sh)";
  Sandbox box;
  const Result c = box.run(
      "capture gl --frame 3 --spp 4 --width 128 --height 128 -o build.trace -- glmark2 --size 128x128 -b "
      "build:duration=0.5",
      kLib);
  ASSERT_EQ(c.code, 0) << c.describe();
  const Captured t = read_trace(box.path("build.trace"));
  ASSERT_FALSE(t.header.draws.empty());
  for (const auto& d : t.header.draws.states())
    EXPECT_EQ(ropsim::draw_kind(d), ropsim::DrawKind::kOpaque) << "draw " << d.draw_id;
  const Result blend = box.run("run --trace build.trace --method blend --quiet -o blend.png");
  ASSERT_EQ(blend.code, 0) << blend.describe();
  const std::string want = slurp(box.path("blend.png"));
  for (const char* m : {"lk", "opaque", "enderton", "hashed-a2c", "reference"}) {
    const Result r = box.run(std::string("run --trace build.trace --method ") + m + " --quiet -o " + m +
                             ".png --report " + m + ".json");
    ASSERT_EQ(r.code, 0) << m << ": " << r.describe();
    EXPECT_EQ(ropsim_test::first_byte_difference(slurp(box.path(std::string(m) + ".png")), want), "")
        << m << "'s PNG differs from blend's";
    const json rep = json::parse(slurp(box.path(std::string(m) + ".json")));
    EXPECT_EQ(rep.at("draw_kinds").at("opaque").get<uint64_t>(), t.fragments.size()) << m;
    if (std::string(m) == "lk") {
      EXPECT_EQ(rep.at("counters").at("tracker_bytes_read").get<uint64_t>(), 0u) << "an opaque draw has no tracker";
      EXPECT_EQ(rep.at("counters").at("sorts").get<uint64_t>(), 0u);
    }
  }
  for (const char* m : {"wboit", "lk+ac", "lk+depth", "lk+depth+ac"}) {
    const Result r = box.run(std::string("run --trace build.trace --method ") + m + " --quiet -o " + m +
                             ".png --report " + m + ".json");
    ASSERT_EQ(r.code, 0) << m << ": " << r.describe();
    const json rep = json::parse(slurp(box.path(std::string(m) + ".json")));
    EXPECT_EQ(rep.at("passes").at(0).get<std::string>(), "prepass") << m;
    EXPECT_EQ(ropsim_test::first_byte_difference(slurp(box.path(std::string(m) + ".png")), want), "")
        << m << "'s PNG differs from blend's";
  }
}

TEST(CaptureGl, CoverageAgreesWithRopsimsRasterizer) {
  ROPSIM_NEEDS_LIBRARY();
  Sandbox box;
  const std::string scene = box.path("cloth.toml");
  std::ofstream(scene) << "width = 64\nheight = 64\nspp = 16\nmesh_dir = \"" ROPSIM_SOURCE_DIR "/traces/scenes/mesh\"\n"
                       << "[camera]\neye = [0.0, 0.35, 2.6]\ntarget = [0.03, 0.03, 0.0]\nfov_y = 40.0\nnear = 1.0\n"
                       << "far = 5.0\n[[object]]\nmesh = \"cloth.obj\"\nopacity = 0.4\norder = \"shuffled\"\n";
  const ropsim::PreparedScene ps = ropsim::prepare_scene(ropsim::load_scene_file(scene));
  write_vertices(ps, box.path("cloth.bin"));
  for (int spp : {16, 64}) {
    SCOPED_TRACE(std::to_string(spp) + " spp");
    const std::string s = std::to_string(spp);
    const Result ref = box.run("capture cloth.toml --spp " + s + " --quiet -o ref" + s + ".trace");
    ASSERT_EQ(ref.code, 0) << ref.describe();
    const Result gl = box.run("capture gl --frame 1 --spp " + s + " --quiet -o gl" + s + ".trace -- " +
                                  gl_program("gl_mesh") + " --size 64x64 --vertices cloth.bin",
                              kLib);
    ASSERT_EQ(gl.code, 0) << gl.describe();
    const auto a = coverage_of(read_trace(box.path("ref" + s + ".trace")));
    const auto b = coverage_of(read_trace(box.path("gl" + s + ".trace")));
    uint64_t either = 0, differ = 0;
    auto it = b.begin();
    for (const auto& [key, m] : a) {
      const auto jt = b.find(key);
      const uint64_t other = jt == b.end() ? 0 : jt->second;
      either += popcount(m | other);
      differ += popcount(m ^ other);
    }
    for (; it != b.end(); ++it)
      if (!a.count(it->first)) either += popcount(it->second), differ += popcount(it->second);
    ASSERT_GT(either, 1000u) << "the cloth covers too little to compare";
    EXPECT_LE(double(differ), 0.001 * double(either)) << differ << " of " << either << " covered samples differ";
  }
}

// A shader's discards: no fragment inside the discarded region, every pixel
// outside it fully covered.
TEST(CaptureGl, DiscardedFragmentsAreNotInTheTrace) {
  ROPSIM_NEEDS_LIBRARY();
  Sandbox box;
  const Result r =
      box.run("capture gl --frame 1 --spp 4 --quiet -o d.trace -- " + gl_program("gl_discard") + " --size 64x48", kLib);
  ASSERT_EQ(r.code, 0) << r.describe();
  const Captured c = read_trace(box.path("d.trace"));
  ASSERT_EQ(c.header.width, 64u);
  ASSERT_EQ(c.header.height, 48u);
  std::map<std::pair<uint32_t, uint32_t>, uint64_t> cov;
  for (const auto& f : c.fragments) cov[{f.x, f.y}] |= f.coverage;
  uint64_t outside = 0;
  for (uint32_t y = 0; y < 48; ++y)
    for (uint32_t x = 0; x < 64; ++x) {
      const float cx = float(x) + 0.5f - 32.0f, cy = float(y) + 0.5f - 24.0f;
      const bool discarded = cx * cx + cy * cy < 0.0625f * 64.0f * 64.0f || float(x) + 0.5f < 16.0f;
      const auto it = cov.find({x, y});
      if (discarded) {
        EXPECT_TRUE(it == cov.end()) << "a fragment at (" << x << ", " << y << ") the shader discards";
      } else {
        ++outside;
        EXPECT_TRUE(it != cov.end() && it->second == 0xF) << "pixel (" << x << ", " << y << ") not fully covered";
      }
    }
  EXPECT_GT(outside, 1000u);
}

// The fixed-function draw (vertex colour, texture MODULATE, alpha test) and the
// same frame drawn by the equivalent shader give the same fragments (vertices
// from fixed-function arrays). Given through glBegin/glEnd, the draw is
// either captured the same way or named as not captured, never dropped
// silently.
TEST(CaptureGl, FixedFunctionMatchesTheEquivalentShader) {
  ROPSIM_NEEDS_LIBRARY();
  Sandbox box;
  for (const char* mode : {"ff", "shader"}) {
    const Result r = box.run(std::string("capture gl --frame 1 --spp 4 -o ") + mode + ".trace -- " +
                                 gl_program("gl_fixed_function") + " --size 64x64 --mode " + mode,
                             kLib);
    ASSERT_EQ(r.code, 0) << r.describe();
    EXPECT_EQ(r.err.find("not in the trace"), std::string::npos) << "every draw is inside the subset\n" << r.describe();
  }
  const Captured a = read_trace(box.path("ff.trace")), b = read_trace(box.path("shader.trace"));
  ASSERT_GT(a.fragments.size(), 500u);
  auto expect_same = [](const Captured& a, const Captured& b, const char* what) {
    ASSERT_EQ(a.fragments.size(), b.fragments.size()) << what;
    size_t bad = 0;
    for (size_t i = 0; i < a.fragments.size() && bad < 5; ++i) {
      const auto &f = a.fragments[i], &g = b.fragments[i];
      bool same = f.x == g.x && f.y == g.y && f.prim_id == g.prim_id && f.coverage == g.coverage &&
                  std::abs(f.alpha - g.alpha) <= 1e-5f;
      for (int k = 0; k < 3; ++k) same = same && std::abs(f.rgb[size_t(k)] - g.rgb[size_t(k)]) <= 1e-5f;
      if (!same) {
        ++bad;
        ADD_FAILURE() << what << ": fragment " << i << " differs: (" << f.x << ", " << f.y << ") rgb " << f.rgb[0]
                      << " " << f.rgb[1] << " " << f.rgb[2] << " a " << f.alpha << " against (" << g.x << ", " << g.y
                      << ") rgb " << g.rgb[0] << " " << g.rgb[1] << " " << g.rgb[2] << " a " << g.alpha;
      }
    }
  };
  expect_same(a, b, "fixed function against the shader");
  // A GLSL program under GL's alpha test: the capture applies the test before
  // its record, so the fragments are those of the shader that discards.
  const Result at = box.run("capture gl --frame 1 --spp 4 -o at.trace -- " + gl_program("gl_fixed_function") +
                                " --size 64x64 --mode shader-alpha-test",
                            kLib);
  ASSERT_EQ(at.code, 0) << at.describe();
  EXPECT_EQ(at.err.find("not in the trace"), std::string::npos) << at.describe();
  expect_same(b, read_trace(box.path("at.trace")), "GL's alpha test against the shader's discard");
  for (const char* mode : {"ff", "shader"}) {
    const std::string t = std::string(mode) + "-immediate.trace";
    const Result r = box.run("capture gl --frame 1 --spp 4 -o " + t + " -- " + gl_program("gl_fixed_function") +
                                 " --size 64x64 --submit immediate --mode " + mode,
                             kLib);
    ASSERT_EQ(r.code, 0) << r.describe();
    if (r.err.find("not in the trace") != std::string::npos) {
      EXPECT_NE(r.out.find("1 not captured"), std::string::npos) << r.describe();
      EXPECT_TRUE(read_trace(box.path(t)).fragments.empty()) << r.describe();
    } else {
      expect_same(a, read_trace(box.path(t)), "glBegin/glEnd against arrays");
    }
  }
}

// API order: at a pixel every primitive and instance covers, the fragments
// come in submission order: draw 0's primitives 0, 1, 2, then draw 1's
// instances 0, 1, 2 (told apart by their colours).
TEST(CaptureGl, FragmentsComeInApiOrder) {
  ROPSIM_NEEDS_LIBRARY();
  Sandbox box;
  const Result r =
      box.run("capture gl --frame 1 --quiet -o o.trace -- " + gl_program("gl_order") + " --size 64x64", kLib);
  ASSERT_EQ(r.code, 0) << r.describe();
  const Captured c = read_trace(box.path("o.trace"));
  const float expect[6][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 0}, {0, 1, 1}, {1, 0, 1}};
  for (const auto& [x, y] : std::vector<std::pair<uint16_t, uint16_t>>{{32, 32}, {31, 31}, {30, 33}}) {
    std::vector<ropsim::Fragment> at;
    for (const auto& f : c.fragments)
      if (f.x == x && f.y == y) at.push_back(f);
    ASSERT_EQ(at.size(), 6u) << "pixel (" << x << ", " << y << ")";
    for (size_t i = 0; i < 6; ++i) {
      EXPECT_EQ(at[i].draw_id, i < 3 ? 0u : 1u) << "fragment " << i << " at (" << x << ", " << y << ")";
      for (int k = 0; k < 3; ++k)
        EXPECT_NEAR(at[i].rgb[size_t(k)], expect[i][k], 1e-6) << "fragment " << i << " at (" << x << ", " << y << ")";
      EXPECT_NEAR(at[i].alpha, 0.5f, 1e-6);
    }
  }
}

// --target fbo:1 captures the draw into the framebuffer object, at its size;
// presented, the post-process quad; --list shows both framebuffers.
TEST(CaptureGl, TargetSelectsTheFramebuffer) {
  ROPSIM_NEEDS_LIBRARY();
  Sandbox box;
  const std::string app = gl_program("gl_fbo") + " --size 64x48 --fbo-size 40x24";
  const Result l = box.run("capture gl --frame 1 --list --json -- " + app, kLib);
  ASSERT_EQ(l.code, 0) << l.describe();
  const json list = json::parse(l.out);
  std::set<std::string> names;
  for (const auto& f : list.at("framebuffers")) names.insert(f.at("name").get<std::string>());
  EXPECT_EQ(names, (std::set<std::string>{"fbo 1", "presented"})) << l.out;
  // A trace numbers only the draws into its target: a draw's id in the trace
  // is its `trace_draw` in the list of that target.
  auto trace_draw = [&](const std::string& target, const std::string& draw) -> int64_t {
    const Result t = box.run("capture gl --frame 1 --list --json " + target + " -- " + app, kLib);
    EXPECT_EQ(t.code, 0) << t.describe();
    if (t.code != 0) return -1;
    const json listed = json::parse(t.out);
    for (const auto& d : listed.at("draws"))
      if (d.at("name").get<std::string>() == draw && !d.at("trace_draw").is_null())
        return d.at("trace_draw").get<int64_t>();
    ADD_FAILURE() << "draw " << draw << " is not in the trace of " << (target.empty() ? "presented" : target) << ": "
                  << t.out;
    return -1;
  };
  std::map<std::string, int64_t> index = {{"scene", trace_draw("--target fbo:1", "scene")},
                                          {"post-process", trace_draw("", "post-process")}};
  ASSERT_TRUE(index["scene"] >= 0 && index["post-process"] >= 0);
  ASSERT_EQ(box.run("capture gl --frame 1 --target fbo:1 --quiet -o f.trace -- " + app, kLib).code, 0);
  ASSERT_EQ(box.run("capture gl --frame 1 --quiet -o p.trace -- " + app, kLib).code, 0);
  const Captured f = read_trace(box.path("f.trace")), p = read_trace(box.path("p.trace"));
  EXPECT_EQ(f.header.width, 40u);
  EXPECT_EQ(f.header.height, 24u);
  ASSERT_FALSE(f.fragments.empty());
  size_t shown = 0;
  for (const auto& fr : f.fragments)
    if ((int64_t(fr.draw_id) != index["scene"] || fr.rgb != std::array<float, 3>{1, 0, 0}) && shown++ < 5)
      ADD_FAILURE() << "fbo:1: a fragment of draw " << fr.draw_id << " rgb " << fr.rgb[0] << " " << fr.rgb[1] << " "
                    << fr.rgb[2] << ": only the red triangle (draw " << index["scene"] << ") goes into FBO 1";
  EXPECT_EQ(p.header.width, 64u);
  EXPECT_EQ(p.header.height, 48u);
  std::set<std::pair<uint16_t, uint16_t>> pixels;
  shown = 0;
  for (const auto& fr : p.fragments) {
    if (int64_t(fr.draw_id) != index["post-process"] && shown++ < 5)
      ADD_FAILURE() << "presented: a fragment of draw " << fr.draw_id << ": only the post-process quad (draw "
                    << index["post-process"] << ") goes into the window; the blit is a copy";
    pixels.insert({fr.x, fr.y});
  }
  EXPECT_EQ(pixels.size(), 64u * 48u) << "the post-process quad covers the window";
  expect_error(box, "capture gl --frame 1 --target fbo:9 -o x.trace -- " + app, kLib, {"fbo"});
}

// The same frame captured twice is byte-identical, whatever llvmpipe's thread
// count.
TEST(CaptureGl, CapturesAreByteIdenticalForEveryThreadCount) {
  ROPSIM_NEEDS_LIBRARY();
  Sandbox box;
  const std::string scene = box.path("cloth.toml");
  std::ofstream(scene) << "width = 64\nheight = 64\nmesh_dir = \"" ROPSIM_SOURCE_DIR "/traces/scenes/mesh\"\n"
                       << "[camera]\neye = [0.0, 0.35, 2.6]\ntarget = [0.03, 0.03, 0.0]\nfov_y = 40.0\nnear = 1.0\n"
                       << "far = 5.0\n[[object]]\nmesh = \"cloth.obj\"\nopacity = 0.4\n";
  write_vertices(ropsim::prepare_scene(ropsim::load_scene_file(scene)), box.path("cloth.bin"));
  for (const char* threads : {"1", "2"})
    for (const char* app : {"gl_mesh", "gl_order"}) {
      const Result r = box.run(std::string("capture gl --frame 1 --spp 16 --quiet -o ") + app + threads + ".trace -- " +
                                   gl_program(app) + " --size 64x64 --vertices cloth.bin",
                               kLib + "LP_NUM_THREADS=" + threads);
      ASSERT_EQ(r.code, 0) << r.describe();
    }
  for (const char* app : {"gl_mesh", "gl_order"}) {
    const std::string a = slurp(box.path(std::string(app) + "1.trace")),
                      b = slurp(box.path(std::string(app) + "2.trace"));
    EXPECT_FALSE(a.empty());
    EXPECT_EQ(ropsim_test::first_byte_difference(a, b), "") << app << ": LP_NUM_THREADS=1 and 2 give different traces";
  }
}

// A draw that overflows its node store is drawn again with room for its
// fragments, to the same trace. Past the store's capacity a fragment finds
// no node of its own and counts again in every pass, so the count is more
// than the draw's fragments: a draw that fits the largest store is still
// captured, and one that does not is a one-line error and no trace.
TEST(CaptureGl, ADrawThatOverflowsItsNodesIsDrawnAgainToTheSameTrace) {
  ROPSIM_NEEDS_LIBRARY();
  Sandbox box;
  const std::string scene = box.path("cloth.toml");
  std::ofstream(scene) << "width = 64\nheight = 64\nmesh_dir = \"" ROPSIM_SOURCE_DIR "/traces/scenes/mesh\"\n"
                       << "[camera]\neye = [0.0, 0.35, 2.6]\ntarget = [0.03, 0.03, 0.0]\nfov_y = 40.0\nnear = 1.0\n"
                       << "far = 5.0\n[[object]]\nmesh = \"cloth.obj\"\nopacity = 0.4\n";
  write_vertices(ropsim::prepare_scene(ropsim::load_scene_file(scene)), box.path("cloth.bin"));
  const auto capture = [&](const std::string& out, const std::string& env) {
    return box.run("capture gl --frame 1 --spp 16 --quiet -o " + out + " -- " + gl_program("gl_mesh") +
                       " --size 64x64 --vertices cloth.bin",
                   kLib + env);
  };
  Result r = capture("whole.trace", "");
  ASSERT_EQ(r.code, 0) << r.describe();
  std::map<uint32_t, uint64_t> per_draw;
  for (const ropsim::Fragment& f : read_trace(box.path("whole.trace")).fragments) ++per_draw[f.draw_id];
  uint64_t largest = 0;
  for (const auto& [draw, n] : per_draw) largest = std::max(largest, n);
  ASSERT_GT(largest, 4u * 64u) << "the test needs a draw of several stores of 64 nodes";
  const std::string whole = slurp(box.path("whole.trace"));
  r = capture("small.trace", "ROPSIM_TEST_GL_NODES=64");
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_EQ(ropsim_test::first_byte_difference(whole, slurp(box.path("small.trace"))), "")
      << "a first store of 64 nodes gives another trace";
  // Twice the draw's fragments: room for its nodes, far less than the
  // count a store of 64 nodes reaches over 17 passes.
  r = capture("fits.trace", "ROPSIM_TEST_GL_NODES=64 ROPSIM_TEST_GL_MAX_NODES=" + std::to_string(2 * largest));
  ASSERT_EQ(r.code, 0) << "a largest store of " << 2 * largest << " nodes holds the largest draw's " << largest
                       << " fragments: " << r.describe();
  EXPECT_EQ(ropsim_test::first_byte_difference(whole, slurp(box.path("fits.trace"))), "")
      << "a store grown up to its limit gives another trace";
  const uint64_t half = largest / 2 / 64 * 64;  // a limit of whole stores of 64 nodes, too small
  r = capture("short.trace", "ROPSIM_TEST_GL_NODES=64 ROPSIM_TEST_GL_MAX_NODES=" + std::to_string(half));
  EXPECT_EQ(r.code, 1) << r.describe();
  EXPECT_NE(r.err.find("more fragments than the " + std::to_string(half) + " nodes a storage block holds"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(box.path("short.trace")));
}

// glretrace replaying an apitrace trace of a program gives the same
// fragments as the program run live.
TEST(CaptureGl, ReplayCapturesWhatTheApplicationDrewLive) {
  ROPSIM_NEEDS_LIBRARY();
#ifdef ROPSIM_GL_TEST_PROGRAMS
  Sandbox box;
  const std::string t = record_apitrace(box);
  ASSERT_FALSE(t.empty());
  ASSERT_EQ(box.run("capture gl --apitrace " + t + " --frame 1 --spp 4 --quiet -o replay.rop", kLib).code, 0);
  ASSERT_EQ(
      box.run("capture gl --frame 1 --spp 4 --quiet -o live.rop -- " + gl_program("gl_order") + " --frames 3", kLib)
          .code,
      0);
  const Captured a = read_trace(box.path("live.rop")), b = read_trace(box.path("replay.rop"));
  ASSERT_GT(a.fragments.size(), 1000u);
  ASSERT_EQ(a.fragments.size(), b.fragments.size());
  for (size_t i = 0; i < a.fragments.size(); ++i) {
    const auto &f = a.fragments[i], &g = b.fragments[i];
    ASSERT_EQ(ropsim_test::Fields()
                  .eq("draw_id", f.draw_id, g.draw_id)
                  .eq("prim_id", f.prim_id, g.prim_id)
                  .eq("x", f.x, g.x)
                  .eq("y", f.y, g.y)
                  .eq("coverage", f.coverage, g.coverage)
                  .eq("rgb", f.rgb, g.rgb)
                  .eq("alpha", f.alpha, g.alpha)
                  .str(),
              "")
        << "fragment " << i << " differs between the live run and the replay";
  }
#endif
}

// The benchmark's modes (scripts/bench_capture_gl.sh): ROPSIM_GL_TIMES writes
// the capture's phase times; ROPSIM_GL_RENDER_PASSES=1 renders the passes with
// the application's programs and makes no records, only with a list.
TEST(CaptureGl, TheBenchmarksModesTimeThePhasesAndRenderThePassesAlone) {
  ROPSIM_NEEDS_LIBRARY();
  Sandbox box;
  const std::string app = " -- " + gl_program("gl_order") + " --frames 3";
  ASSERT_EQ(box.run("capture gl --frame 1 --spp 4 --quiet -o t.trace" + app,
                    kLib + "ROPSIM_GL_TIMES=" + box.path("capture.json"))
                .code,
            0);
  const json c = json::parse(slurp(box.path("capture.json")));
  for (const char* phase : {"passes", "read_back", "build", "write"})
    EXPECT_GT(c.at(phase).get<double>(), 0.0) << phase << "\n" << c.dump();
  const Result r = box.run("capture gl --frame 1 --spp 4 --list --json" + app,
                           kLib + "ROPSIM_GL_RENDER_PASSES=1 ROPSIM_GL_TIMES=" + box.path("passes.json"));
  ASSERT_EQ(r.code, 0) << r.describe();
  const json p = json::parse(slurp(box.path("passes.json")));
  EXPECT_GT(p.at("passes").get<double>(), 0.0) << p.dump();
  for (const char* phase : {"read_back", "build", "write"})
    EXPECT_EQ(p.at(phase).get<double>(), 0.0) << phase << ": the passes alone make no nodes\n" << p.dump();
  expect_error(box, "capture gl --frame 1 --spp 4 -o u.trace" + app, kLib + "ROPSIM_GL_RENDER_PASSES=1",
               {"ROPSIM_GL_RENDER_PASSES=1 needs ROPSIM_GL_LIST_ONLY=1"});
}

// The suite's glmark2 entries (traces/apps) capture with `capture gl --app`,
// and trace info's statistics of each are right: its draws by kind are the
// capture list's draws into the target, and its share of covered samples
// that are transparent (src-over and premultiplied-over draws) equals the
// share computed independently from each draw's occlusion query
// (GL_SAMPLES_PASSED with the depth test off, in the same run), exactly.
TEST(CaptureGl, TheSuitesGlmark2EntriesCaptureAndTheirStatisticsAreRight) {
  ROPSIM_NEEDS_LIBRARY();
  ASSERT_FALSE(ropsim::find_executable("glmark2").empty())
      << "glmark2 not found: install glmark2-x11 (scripts/deps.sh)";
  const fs::path apps = fs::path(ROPSIM_SOURCE_DIR) / "traces" / "apps";
  size_t entries = 0;
  for (const char* name : {"glmark2-jellyfish", "glmark2-pulsar", "glmark2-desktop", "glmark2-build"}) {
    SCOPED_TRACE(name);
    Sandbox box;
    const std::string entry = (apps / (std::string(name) + ".toml")).string();
    const Result c =
        box.run("capture gl --app '" + entry + "' --count-samples --keep-control kc -o t.rtr --quiet", kLib);
    ASSERT_EQ(c.code, 0) << c.describe();
    ++entries;
    const json list = json::parse(slurp(box.work() / "kc" / "list.json"));
    const json status = json::parse(slurp(box.work() / "kc" / "status.json"));
    const std::string target = status.at("target").get<std::string>();
    const std::string fb = target.rfind("fbo:", 0) == 0 ? "fbo " + target.substr(4) : target;
    uint64_t all = 0, transparent = 0, draws = 0;
    std::map<std::string, uint64_t> kinds;
    for (const json& d : list.at("draws")) {
      if (d.at("framebuffer").get<std::string>() != fb) continue;
      ASSERT_TRUE(d.at("samples_passed").is_number()) << d.dump();
      const uint64_t passed = d.at("samples_passed").get<uint64_t>();
      const std::string kind = d.at("kind").get<std::string>();
      all += passed;
      if (kind == "src-over" || kind == "premultiplied-over") transparent += passed;
      ++kinds[kind];
      ++draws;
    }
    ASSERT_GT(all, 0u) << "the entry's frame draws nothing into " << fb;
    const Result info = box.run("trace info t.rtr --json");
    ASSERT_EQ(info.code, 0) << info.describe();
    const json j = json::parse(info.out);
    EXPECT_EQ(j.at("covered_samples").get<uint64_t>(), all) << "covered samples against the occlusion queries";
    EXPECT_EQ(j.at("transparent").at("covered_samples").get<uint64_t>(), transparent);
    EXPECT_DOUBLE_EQ(j.at("transparent").at("covered_samples_share").get<double>(), double(transparent) / double(all));
    EXPECT_EQ(j.at("draws").get<uint64_t>(), draws);
    for (const auto& [kind, n] : kinds) EXPECT_EQ(j.at("draw_kinds").at(kind).at("draws").get<uint64_t>(), n) << kind;
    if (std::string(name) == "glmark2-build")
      EXPECT_EQ(transparent, 0u) << "the opaque control has no transparent sample";
    else
      EXPECT_GT(transparent, 0u) << "a blending scene's frame has transparent samples";
  }
  EXPECT_EQ(entries, 4u);
}

// A study of the suite's glmark2 entries (captured by the study, once per
// spp, at the entries' 128 x 128) with a subset of studies/real-frames.toml's
// axes: every point is in results.db, with its reference's RMSE and its
// cycles; on the opaque control every method's image is blend's (RMSE 0
// against the same reference, and the same max error).
TEST(CaptureGl, TheRealFramesStudyRunsOnTheGlmark2Entries) {
  ROPSIM_NEEDS_LIBRARY();
  ASSERT_FALSE(ropsim::find_executable("glmark2").empty())
      << "glmark2 not found: install glmark2-x11 (scripts/deps.sh)";
  Sandbox box;
  const fs::path apps = fs::path(ROPSIM_SOURCE_DIR) / "traces" / "apps";
  std::ofstream(box.work() / "s.toml") << "[study]\nname = \"real-frames-ci\"\n[inputs]\napps = [\"" +
                                              (apps / "glmark2-jellyfish.toml").string() + "\", \"" +
                                              (apps / "glmark2-desktop.toml").string() + "\", \"" +
                                              (apps / "glmark2-build.toml").string() +
                                              "\"]\n[axes]\nmethod = [\"blend\", \"lk\", \"hashed-a2c\", \"wboit\", "
                                              "\"lk+depth+ac\"]\nspp = [4]\nfidelity = \"cycle\"\n";
  const Result r = box.run("study run s.toml --out st -j 2 --quiet", kLib);
  ASSERT_EQ(r.code, 0) << r.describe();
  const Result e = box.run("study export st --out r.csv");
  ASSERT_EQ(e.code, 0) << e.describe();
  std::ifstream csv(box.work() / "r.csv");
  std::string head;
  std::getline(csv, head);
  const std::vector<std::string> cols = ropsim_test::csv_fields(head);
  auto col = [&](const std::string& name) {
    const auto it = std::find(cols.begin(), cols.end(), name);
    EXPECT_NE(it, cols.end()) << name << " is not a column of the export";
    return size_t(it - cols.begin());
  };
  const size_t input = col("input"), method = col("method"), status = col("status"),
               rmse = col("vs_reference.rmse_8bit"), cycles = col("timing.total_cycles");
  std::set<std::pair<std::string, std::string>> seen;
  std::map<std::string, std::string> build_rmse;
  for (std::string line; std::getline(csv, line);) {
    const std::vector<std::string> f = ropsim_test::csv_fields(line);
    ASSERT_GT(f.size(), std::max({input, method, status, rmse, cycles})) << line;
    EXPECT_EQ(f[status], "ok") << line;
    EXPECT_FALSE(f[rmse].empty()) << f[input] << " " << f[method] << ": no RMSE";
    EXPECT_GT(std::atof(f[cycles].c_str()), 0.0) << f[input] << " " << f[method] << ": no cycles";
    seen.emplace(f[input], f[method]);
    if (f[input] == "glmark2-build") build_rmse[f[method]] = f[rmse];
  }
  EXPECT_EQ(seen.size(), 15u) << "3 entries x 5 methods";
  ASSERT_EQ(build_rmse.size(), 5u);
  for (const auto& [m, v] : build_rmse) EXPECT_EQ(v, build_rmse.at("blend")) << m << " on the opaque control";
}

// The real library's errors: an application that exits before frame N, a
// frame past the end of a replayed trace.
TEST(CaptureGl, FramesThatNeverComeAreErrors) {
  ROPSIM_NEEDS_LIBRARY();
  Sandbox box;
  expect_error(box, "capture gl --frame 5 -o t.trace -- " + gl_program("gl_order") + " --frames 2", kLib,
               {"exited after 2 frames, before frame 5"});
}

}  // namespace
