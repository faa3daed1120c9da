// `ropsim capture gl`'s run: one frame of a real OpenGL application (run live
// under a private Xvfb, or an apitrace trace replayed by glretrace) into a
// trace, through the capture library preloaded into it (docs/capture.md
// "Capturing a frame of an OpenGL application"). It owns the processes: it
// starts Xvfb and the application, waits for the library's status, and stops
// every child it started on every path (success, error, timeout, a signal).
#include "traces/glcapture/gl_capture.h"

#include <fmt/format.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>

#include "util/errors.h"
#include "util/output_file.h"

namespace fs = std::filesystem;

namespace ropsim {

namespace {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

constexpr const char* kLibraryName = "libropsim_glcapture.so";
constexpr const char* kInstall = "scripts/deps.sh installs it";

/// The capture library: $ROPSIM_GLCAPTURE_LIB, else beside this executable.
std::string find_capture_library() {
  if (const char* env = std::getenv("ROPSIM_GLCAPTURE_LIB"); env && *env) {
    struct stat st;
    if (::stat(env, &st) != 0 || !S_ISREG(st.st_mode))
      throw UserError(fmt::format("ROPSIM_GLCAPTURE_LIB={}: no such library file", env));
    return fs::absolute(env).string();
  }
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  const fs::path lib = (ec ? fs::path(".") : self.parent_path()) / kLibraryName;
  if (!fs::is_regular_file(lib, ec))
    throw UserError(fmt::format(
        "the GL capture library {} is not beside ropsim ({}) and ROPSIM_GLCAPTURE_LIB is not set: build the CMake "
        "target ropsim_glcapture (it needs the GL/EGL development packages; {})",
        kLibraryName, lib.parent_path().string(), kInstall));
  return lib.string();
}

std::string need_program(const std::string& name, const std::string& package) {
  const std::string p = find_executable(name);
  if (p.empty())
    throw UserError(fmt::format("{} not found on PATH: install the Debian package {} ({})", name, package, kInstall));
  return p;
}

json read_json(const fs::path& p, const std::string& what) {
  std::ifstream f(p);
  if (!f) throw UserError(fmt::format("{}: the capture library wrote no {}", what, p.filename().string()));
  try {
    return json::parse(f);
  } catch (const json::exception& e) {
    throw UserError(fmt::format("{}: the capture library's {} is not JSON: {}", what, p.filename().string(), e.what()));
  }
}

/// The private folder the library writes its files to: --keep-control's
/// (created; an existing one must be empty), else a new one in $TMPDIR that
/// is removed again.
class ControlDir {
 public:
  explicit ControlDir(const std::string& keep) : keep_(!keep.empty()) {
    std::error_code ec;
    if (keep_) {
      path_ = fs::absolute(keep);
      if (fs::exists(path_, ec)) {
        if (!fs::is_directory(path_, ec) || !fs::is_empty(path_, ec))
          throw UserError(fmt::format("--keep-control {}: exists and is not an empty folder", keep));
      } else {
        fs::create_directories(path_, ec);
        if (ec) throw UserError(fmt::format("--keep-control {}: cannot create the folder: {}", keep, ec.message()));
      }
      return;
    }
    const char* tmp = std::getenv("TMPDIR");
    std::string templ = std::string(tmp && *tmp ? tmp : "/tmp") + "/ropsim-gl.XXXXXX";
    if (!::mkdtemp(templ.data()))
      throw SystemError(fmt::format("{}: cannot create a private folder: {}", templ, std::strerror(errno)), errno);
    path_ = templ;
  }
  ~ControlDir() { remove(); }
  /// Removes the folder (not a --keep-control one). Idempotent, no-throw.
  void remove() noexcept {
    std::error_code ec;
    if (!keep_ && !path_.empty()) fs::remove_all(path_, ec);
    if (!keep_) path_.clear();
  }
  const fs::path& path() const { return path_; }
  fs::path operator/(const char* name) const { return path_ / name; }

 private:
  fs::path path_;
  bool keep_;
};

/// What `apitrace info` says of a trace: its frame count (FramesCount, the
/// number of frame-ending calls) and its API ("OpenGL + GLX/WGL/CGL",
/// "OpenGL + EGL"...); frames -1 when apitrace is not installed.
struct ApitraceInfo {
  int64_t frames = -1;
  std::string api;
};

ApitraceInfo apitrace_info(const std::string& file, const ControlDir& dir, const volatile sig_atomic_t* stop) {
  const std::string apitrace = find_executable("apitrace");
  if (apitrace.empty()) return {};
  ChildProcess::Spec spec;
  spec.argv = {apitrace, "info", file};
  spec.output = (dir / "apitrace-info.json").string();
  ChildProcess info(spec);
  const auto e = info.wait_until(Clock::now() + std::chrono::seconds(60), stop);
  if (!e) return {};  // interrupted (the caller reraises) or too slow: glretrace's own count decides
  std::ifstream f(spec.output);
  json j;
  try {
    j = json::parse(f);
  } catch (const json::exception&) {
  }
  if (!e->success() || !j.is_object() || !j.contains("FramesCount"))
    throw UserError(fmt::format("{}: not an apitrace trace (apitrace info: {})", file, last_line_of(spec.output)));
  return {json_field<int64_t>(j, "FramesCount", -1), json_field<std::string>(j, "API", "")};
}

}  // namespace

GlCaptureResult run_gl_capture(const GlCaptureRequest& o, StopSignals* signals) {
  GlCaptureResult res;
  const bool replay = !o.apitrace.empty();
  if (replay && !o.app.empty())
    throw UserError("capture gl: give either an application after -- or --apitrace FILE, not both");
  if (!replay && o.app.empty())
    throw UserError(
        "capture gl: give the application to run after -- (capture gl --frame N -o T -- APP ARGS...) "
        "or --apitrace FILE");
  if (o.list && !o.out.empty()) throw UserError("capture gl: --list writes no trace: leave out -o");
  if (!o.list && o.out.empty()) throw UserError("capture gl: give -o TRACE (or --list)");
  if (o.reference_msaa && o.keep_control.empty())
    throw UserError("capture gl: --reference-msaa writes its image into the --keep-control folder: give one");

  // Everything that can be checked before a process starts.
  std::string program;  // what runs: the application or glretrace
  std::vector<std::string> argv;
  std::string what;  // names the application (or the trace) in messages
  if (replay) {
    std::ifstream probe(o.apitrace, std::ios::binary);
    if (!probe) throw UserError(fmt::format("{}: cannot open: {}", o.apitrace, std::strerror(errno)));
    program = need_program("glretrace", "apitrace");  // or eglretrace, by the trace's API (below)
    argv = {program, o.apitrace};
    what = o.apitrace;
  } else {
    what = o.what.empty() ? o.app[0] : o.what;
    program = find_executable(o.app[0]);
    if (program.empty())
      throw UserError(fmt::format(
          "{}: application not found: {} ({}){}", what, o.app[0],
          o.app[0].find('/') != std::string::npos ? "no such executable file" : "no such program on PATH",
          o.package.empty()
              ? ""
              : fmt::format(": install the Debian package {} (scripts/deps.sh --apps installs it)", o.package)));
    argv = o.app;
    argv[0] = program;
  }
  const std::string library = find_capture_library();
  const std::string xvfb = need_program("Xvfb", "xvfb");
  OutputPlan plan;
  if (replay) plan.input("--apitrace", o.apitrace);
  plan.output("-o", o.out);
  plan.check();

  const volatile sig_atomic_t* const stop = signals ? signals->flag() : nullptr;
  ControlDir dir(o.keep_control);
  const auto interrupted = [&] { return signals && signals->caught() != 0; };
  // A signal ends ropsim as it would have, once the children are stopped
  // (the child objects' destructors) and the private folder is removed.
  const auto stop_if_interrupted = [&] {
    if (!interrupted()) return;
    dir.remove();
    if (signals) signals->reraise();
  };
  try {
    if (replay) {
      const ApitraceInfo info = apitrace_info(o.apitrace, dir, stop);
      stop_if_interrupted();
      if (info.frames >= 0 && o.frame >= info.frames)
        throw UserError(fmt::format("{}: --frame {} is past the end of the trace ({}, 0..{})", o.apitrace, o.frame,
                                    info.frames == 1 ? "1 frame" : fmt::format("{} frames", info.frames),
                                    info.frames - 1));
      if (info.api.find("EGL") != std::string::npos) argv[0] = need_program("eglretrace", "apitrace");
    }

    std::optional<ChildExit> ended;
    {
      VirtualDisplay display(xvfb, o.width, o.height, (dir / "xvfb.log").string(), std::chrono::seconds(20), stop);
      // The library first; what the caller preloads stays.
      const char* outer = std::getenv("LD_PRELOAD");
      const std::string preload = library + (outer && *outer ? std::string(":") + outer : "");
      // glibc's malloc on transparent huge pages: llvmpipe's buffers (the
      // capture's node buffers are hundreds of MB) are memory touched once,
      // and the faults of a fresh 4 KiB page cost tens of times writing it.
      const char* tunables = std::getenv("GLIBC_TUNABLES");
      const std::string huge =
          std::string(tunables && *tunables ? std::string(tunables) + ":" : "") + "glibc.malloc.hugetlb=1";
      std::vector<std::pair<std::string, std::string>> env = {
          {"DISPLAY", display.display()},
          {"LD_PRELOAD", preload},
          {"LIBGL_ALWAYS_SOFTWARE", "1"},
          {"GALLIUM_DRIVER", "llvmpipe"},
          {"GLIBC_TUNABLES", huge},
          {"ROPSIM_GL_CONTROL", dir.path().string()},
          {"ROPSIM_GL_FRAME", std::to_string(o.frame)},
          {"ROPSIM_GL_SPP", std::to_string(o.spp)},
          {"ROPSIM_GL_TARGET", o.target},
      };
      std::vector<std::string> unset = {
          "ROPSIM_GL_OUT", "ROPSIM_GL_LIST_ONLY", "ROPSIM_GL_COUNT_SAMPLES", "ROPSIM_GL_REFERENCE_MSAA",
          "XAUTHORITY",    "WAYLAND_DISPLAY"};
      if (!o.list) env.emplace_back("ROPSIM_GL_OUT", (dir / "capture.trace").string());
      if (o.list) env.emplace_back("ROPSIM_GL_LIST_ONLY", "1");
      if (o.count_samples) env.emplace_back("ROPSIM_GL_COUNT_SAMPLES", "1");
      if (o.reference_msaa) env.emplace_back("ROPSIM_GL_REFERENCE_MSAA", "4");
      ChildProcess::Spec spec;
      spec.argv = argv;
      spec.env = environment_with(env, unset);
      spec.output = (dir / "application.log").string();
      ChildProcess app(spec);
      const auto deadline =
          Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(o.timeout));
      ended = app.wait_until(deadline, stop);
      if (!ended) {
        app.stop();
        if (interrupted()) {
          // The children are stopped (app above, Xvfb by its destructor) and
          // the private folder removed before the signal ends ropsim.
        } else {
          throw UserError(
              fmt::format("{}: frame {} did not end within {} s (--timeout): stopped it and its process "
                          "group",
                          what, o.frame, o.timeout));
        }
      }
    }
    stop_if_interrupted();

    const fs::path status_path = dir / "status.json";
    if (!fs::exists(status_path)) {
      const std::string said = last_line_of((dir / "application.log").string());
      throw UserError(fmt::format("{} {} before the end of frame {}, without a capture status{}", what,
                                  ended->describe(), o.frame, said.empty() ? "" : " (it said: " + said + ")"));
    }
    const json status = read_json(status_path, what);
    if (!json_field<bool>(status, "ok", false)) {
      std::string error = json_field<std::string>(status, "error", "");
      if (error.empty()) error = "the capture failed (no reason given)";
      if (replay && error.find("exited after") != std::string::npos)
        throw UserError(fmt::format("{}: --frame {} is past the end of the trace ({})", o.apitrace, o.frame, error));
      throw UserError(fmt::format("{}: {}", what, error));
    }
    const json list = read_json(dir / "list.json", what);
    stop_if_interrupted();
    res.status = status;
    res.list = list;
    res.what = what;
    if (o.list) return res;

    // The trace: into -o through the output discipline (atomic, no partial file).
    const fs::path written = dir / "capture.trace";
    std::ifstream in(written, std::ios::binary);
    if (!in) throw UserError(fmt::format("{}: the capture library reported success but wrote no trace", what));
    ensure_parent_dir(o.out);
    uint64_t bytes = 0;
    bool moved = false;
    if (o.keep_control.empty()) {
      // Moved rather than copied where the private folder and -o's are on
      // one file system: the library's file (written, flushed to disk)
      // becomes the output's temporary and is renamed onto -o.
      OutputFile::Options by_name;
      by_name.named = true;
      OutputFile out(o.out, by_name);
      if (::rename(written.c_str(), out.write_name().c_str()) == 0) {
        in.close();
        struct stat st;
        if (::stat(out.write_name().c_str(), &st) == 0) bytes = uint64_t(st.st_size);
        stop_if_interrupted();
        out.commit();
        moved = true;
      }
    }
    if (!moved) {
      OutputFile out(o.out);
      std::vector<char> buf(1 << 20);
      while (in) {
        in.read(buf.data(), std::streamsize(buf.size()));
        const auto n = in.gcount();
        if (n > 0) out.write(buf.data(), size_t(n));
        bytes += uint64_t(n);
      }
      if (in.bad()) throw UserError(fmt::format("{}: cannot read the captured trace", written.string()));
      stop_if_interrupted();
      out.commit();
    }
    res.bytes = bytes;
  } catch (...) {
    stop_if_interrupted();  // an error that is the signal's doing (a child it ended, Xvfb interrupted)
    throw;
  }
  stop_if_interrupted();
  return res;
}

std::string gl_target_name(const std::string& target) {
  return target.rfind("fbo:", 0) == 0 ? "fbo " + target.substr(4) : target;
}

}  // namespace ropsim
