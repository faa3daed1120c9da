// `ropsim capture gl`: one frame of a real OpenGL application (run live under
// a private Xvfb, or an apitrace trace replayed by glretrace) into a trace,
// through the capture library preloaded into it (docs/capture.md "Capturing
// a frame of an OpenGL application"). The command owns the processes: it
// starts Xvfb and the application, waits for the library's status, and stops
// every child it started on every path (success, error, --timeout, Ctrl-C).
#include <fmt/format.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>

#include "child_process.h"
#include "cli_common.h"
#include "cmd_capture.h"
#include "errors.h"
#include "output_file.h"

namespace fs = std::filesystem;

namespace ropsim {

namespace {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

constexpr const char* kLibraryName = "libropsim_glcapture.so";
constexpr const char* kInstall = "scripts/deps.sh installs it";

struct GlCaptureOpts {
  int64_t frame = 0;
  int spp = 1;
  unsigned width = 1280, height = 1024;
  std::string target = "presented";
  double timeout = 120;
  std::string out, apitrace, keep_control;
  bool list = false, json = false, quiet = false, count_samples = false, reference_msaa = false;
  std::vector<std::string> app;
};

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

/// "fbo:N" -> "fbo N" (list.json's framebuffer names); "presented" stays.
std::string target_name(const std::string& target) {
  return target.rfind("fbo:", 0) == 0 ? "fbo " + target.substr(4) : target;
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

template <class T>
T field(const json& j, const char* key, T fallback) {
  const auto it = j.find(key);
  if (it == j.end() || it->is_null()) return fallback;
  try {
    return it->get<T>();
  } catch (const json::exception&) {
    return fallback;
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
  return {field<int64_t>(j, "FramesCount", -1), field<std::string>(j, "API", "")};
}

std::string plural(uint64_t n, const char* one, const char* many) {
  return fmt::format("{} {}", n, n == 1 ? one : many);
}

/// The framebuffers and draws of list.json as two tables.
void print_list(const json& list, const GlCaptureOpts& o, const std::string& what) {
  auto table = [](const std::vector<std::string>& head, const std::vector<std::vector<std::string>>& rows) {
    std::vector<size_t> w(head.size());
    for (size_t c = 0; c < head.size(); ++c) w[c] = head[c].size();
    for (const auto& r : rows)
      for (size_t c = 0; c < r.size() && c < w.size(); ++c) w[c] = std::max(w[c], r[c].size());
    auto line = [&](const std::vector<std::string>& r) {
      std::string s = " ";
      for (size_t c = 0; c < r.size(); ++c)
        s += " " + r[c] + (c + 1 < r.size() ? std::string(w[c] - r[c].size(), ' ') : "");
      fmt::print("{}\n", s);
    };
    line(head);
    for (const auto& r : rows) line(r);
  };
  std::vector<std::vector<std::string>> fbs, draws;
  const json empty = json::array();
  for (const auto& f : list.value("framebuffers", empty))
    fbs.push_back({field<std::string>(f, "name", "?"),
                   fmt::format("{}x{}", field<uint64_t>(f, "width", 0), field<uint64_t>(f, "height", 0)),
                   std::to_string(field<uint64_t>(f, "samples", 0)), field<std::string>(f, "encoding", "?"),
                   std::to_string(field<uint64_t>(f, "draws", 0)), field<bool>(f, "presented", false) ? "yes" : "no"});
  for (const auto& d : list.value("draws", empty)) {
    const auto passed = d.find("samples_passed");
    draws.push_back({std::to_string(field<uint64_t>(d, "index", 0)), field<std::string>(d, "framebuffer", "?"),
                     std::to_string(field<uint64_t>(d, "program", 0)), field<std::string>(d, "name", ""),
                     field<std::string>(d, "kind", "?"), field<std::string>(d, "blend", ""),
                     field<std::string>(d, "depth", ""), std::to_string(field<uint64_t>(d, "fragments", 0)),
                     std::to_string(field<uint64_t>(d, "covered_samples", 0)),
                     passed != d.end() && passed->is_number() ? std::to_string(passed->get<uint64_t>()) : "-"});
  }
  fmt::print("frame {} of {}: {}\n", o.frame, what, plural(fbs.size(), "framebuffer", "framebuffers"));
  table({"framebuffer", "size", "samples", "encoding", "draws", "presented"}, fbs);
  fmt::print("{}\n", plural(draws.size(), "draw", "draws"));
  if (!draws.empty())
    table({"draw", "framebuffer", "program", "name", "kind", "blend", "depth", "fragments", "covered", "passed"},
          draws);
}

int run_capture_gl(const GlCaptureOpts& o, const CLI::App& sub) {
  const bool replay = !o.apitrace.empty();
  if (replay && !o.app.empty())
    throw UserError("capture gl: give either an application after -- or --apitrace FILE, not both");
  if (!replay && o.app.empty())
    throw UserError(
        "capture gl: give the application to run after -- (capture gl --frame N -o T -- APP ARGS...) "
        "or --apitrace FILE");
  if (o.list && !o.out.empty()) throw UserError("capture gl: --list writes no trace: leave out -o");
  if (!o.list && o.out.empty()) throw UserError("capture gl: give -o TRACE (or --list)");
  if (o.json && !o.list) throw UserError("capture gl: --json goes with --list");
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
    program = find_executable(o.app[0]);
    if (program.empty())
      throw UserError(
          fmt::format("{}: application not found ({})", o.app[0],
                      o.app[0].find('/') != std::string::npos ? "no such executable file" : "no such program on PATH"));
    argv = o.app;
    argv[0] = program;
    what = o.app[0];
  }
  const std::string library = find_capture_library();
  const std::string xvfb = need_program("Xvfb", "xvfb");
  OutputPlan plan;
  if (replay) plan.input("--apitrace", o.apitrace);
  plan.output("-o", o.out);
  plan.check();

  StopSignals signals;
  ControlDir dir(o.keep_control);
  const auto interrupted = [&] { return signals.caught() != 0; };
  // A signal ends ropsim as it would have, once the children are stopped
  // (the child objects' destructors) and the private folder is removed.
  const auto stop_if_interrupted = [&] {
    if (!interrupted()) return;
    dir.remove();
    signals.reraise();
  };
  try {
    if (replay) {
      const ApitraceInfo info = apitrace_info(o.apitrace, dir, signals.flag());
      stop_if_interrupted();
      if (info.frames >= 0 && o.frame >= info.frames)
        throw UserError(fmt::format("{}: --frame {} is past the end of the trace ({}, 0..{})", o.apitrace, o.frame,
                                    plural(uint64_t(info.frames), "frame", "frames"), info.frames - 1));
      if (info.api.find("EGL") != std::string::npos) argv[0] = need_program("eglretrace", "apitrace");
    }

    std::optional<ChildExit> ended;
    {
      VirtualDisplay display(xvfb, o.width, o.height, (dir / "xvfb.log").string(), std::chrono::seconds(20),
                             signals.flag());
      // The library first; what the caller preloads stays.
      const char* outer = std::getenv("LD_PRELOAD");
      const std::string preload = library + (outer && *outer ? std::string(":") + outer : "");
      std::vector<std::pair<std::string, std::string>> env = {
          {"DISPLAY", display.display()},
          {"LD_PRELOAD", preload},
          {"LIBGL_ALWAYS_SOFTWARE", "1"},
          {"GALLIUM_DRIVER", "llvmpipe"},
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
      ended = app.wait_until(deadline, signals.flag());
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
    if (!field<bool>(status, "ok", false)) {
      std::string error = field<std::string>(status, "error", "");
      if (error.empty()) error = "the capture failed (no reason given)";
      if (replay && error.find("exited after") != std::string::npos)
        throw UserError(fmt::format("{}: --frame {} is past the end of the trace ({})", o.apitrace, o.frame, error));
      throw UserError(fmt::format("{}: {}", what, error));
    }
    const json list = read_json(dir / "list.json", what);
    stop_if_interrupted();
    if (o.list) {
      if (o.json)
        fmt::print("{}\n", list.dump(2));
      else
        print_list(list, o, what);
      return 0;
    }

    // The trace: into -o through the output discipline (atomic, no partial file).
    const fs::path written = dir / "capture.trace";
    std::ifstream in(written, std::ios::binary);
    if (!in) throw UserError(fmt::format("{}: the capture library reported success but wrote no trace", what));
    ensure_parent_dir(o.out);
    uint64_t bytes = 0;
    {
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

    // The summary: what went into the trace, and every draw that did not.
    const json unsupported = status.value("unsupported", json::array());
    std::set<uint64_t> left_out;
    for (const auto& u : unsupported) left_out.insert(field<uint64_t>(u, "draw", 0));
    std::map<std::string, uint64_t> kinds;  // of the draws in the trace: into the target, captured
    const std::string tname = target_name(field<std::string>(status, "target", o.target));
    for (const auto& d : list.value("draws", json::array()))
      if (field<std::string>(d, "framebuffer", "") == tname && !left_out.count(field<uint64_t>(d, "index", 0)))
        ++kinds[field<std::string>(d, "kind", "other")];
    std::string by_kind;
    for (const char* k : {"opaque", "src-over", "premultiplied-over", "additive", "other"})
      if (kinds.count(k)) by_kind += (by_kind.empty() ? "" : ", ") + fmt::format("{} {}", kinds[k], k);
    for (const auto& u : unsupported)
      std::fprintf(stderr, "ropsim: warning: %s: draw %llu (%s) is not in the trace: %s\n", what.c_str(),
                   static_cast<unsigned long long>(field<uint64_t>(u, "draw", 0)),
                   field<std::string>(u, "name", "?").c_str(), field<std::string>(u, "reason", "?").c_str());
    if (!o.quiet) {
      const uint64_t draws = field<uint64_t>(status, "draws", 0);
      fmt::print("wrote {}: {} bytes, frame {} of {} ({} {}x{}), {} spp, {}{}, {} fragments", o.out, bytes, o.frame,
                 what, tname, field<uint64_t>(status, "width", 0), field<uint64_t>(status, "height", 0),
                 field<uint64_t>(status, "spp", uint64_t(o.spp)), plural(draws, "draw", "draws"),
                 by_kind.empty() ? "" : " (" + by_kind + ")", field<uint64_t>(status, "fragments", 0));
      if (!unsupported.empty()) fmt::print(", {} not captured (unsupported)", unsupported.size());
      fmt::print("\n");
      for (const auto& u : unsupported)
        fmt::print("  not captured: draw {} ({}): {}\n", field<uint64_t>(u, "draw", 0),
                   field<std::string>(u, "name", "?"), field<std::string>(u, "reason", "?"));
    }
  } catch (...) {
    stop_if_interrupted();  // an error that is the signal's doing (a child it ended, Xvfb interrupted)
    throw;
  }
  stop_if_interrupted();
  (void)sub;
  return 0;
}

}  // namespace

std::function<int()> add_capture_gl_command(CLI::App& capture) {
  auto o = std::make_shared<GlCaptureOpts>();
  CLI::App* sub = capture.add_subcommand(
      "gl",
      "Capture one frame of an OpenGL application (run under a private Xvfb with Mesa llvmpipe, or an "
      "apitrace trace replayed by glretrace) into a trace with its draws' state (docs/capture.md)");
  sub->add_option("--frame", o->frame,
                  "The frame to capture: frames count from 0, frame N is the work after the N-th buffer swap")
      ->required()
      ->check(in_range<int64_t>(0))
      ->type_name("N");
  sub->add_option("-o,--out,--output", o->out,
                  "Trace file to write (written atomically: no file on error; docs/outputs.md)")
      ->type_name("FILE");
  sub->add_option("--spp", o->spp, "Samples per pixel of the trace: 1, 2, 4, 8, 16, 32 or 64")
      ->check(CLI::IsMember({1, 2, 4, 8, 16, 32, 64}));
  sub->add_option("--width", o->width, "Width of the virtual X screen in pixels (the application sizes its window)")
      ->check(in_range(16u, 16384u));
  sub->add_option("--height", o->height, "Height of the virtual X screen in pixels")->check(in_range(16u, 16384u));
  sub->add_option("--target", o->target,
                  "The framebuffer captured: presented (what the swap shows) or fbo:N (the framebuffer object named N)")
      ->check(CLI::Validator(
          [](std::string& t) -> std::string {
            if (t == "presented") return "";
            if (t.rfind("fbo:", 0) == 0 && t.size() > 4 && t.size() < 14 &&
                t.find_first_not_of("0123456789", 4) == std::string::npos && std::stoull(t.substr(4)) > 0)
              return "";
            return t + ": not presented or fbo:N (N >= 1, an FBO's GL name)";
          },
          "presented|fbo:N"));
  sub->add_option("--timeout", o->timeout,
                  "Seconds the application may take to reach the end of the frame; then it and its process group are "
                  "stopped and the capture fails")
      ->check(in_range(0.1, 1e6))
      ->type_name("SECONDS");
  sub->add_option("--apitrace", o->apitrace,
                  "Replay this apitrace trace with glretrace instead of running an application")
      ->type_name("FILE");
  sub->add_flag("--list", o->list,
                "Write no trace: list the frame's framebuffers and draws (index, framebuffer, program, kind, blend and "
                "depth state, fragments)");
  sub->add_flag("--json", o->json, "With --list: print the library's list (list.json) as JSON");
  sub->add_option("--keep-control", o->keep_control,
                  "Keep the capture library's files in this folder (created; must be empty): status.json, list.json, "
                  "frame.rgba + frame.json (the frame as the application rendered it), the application's and Xvfb's "
                  "output")
      ->type_name("DIR");
  sub->add_flag("--count-samples", o->count_samples,
                "Also count each draw's samples with an occlusion query (list.json's samples_passed; a cross-check)");
  sub->add_flag("--reference-msaa", o->reference_msaa,
                "Also render the frame's draws into a 4x MSAA copy of the target and keep the resolved image as "
                "frame-msaa4.rgba in --keep-control's folder (the reference at 4 spp)");
  sub->add_flag("--quiet", o->quiet, "Print nothing on success (warnings about draws not captured still go to stderr)");
  sub->add_option("APP", o->app, "The application and its arguments, after --")->type_name("ARGS");
  sub->footer(examples(
      {"ropsim capture gl --frame 5 --spp 4 -o jellyfish.trace -- glmark2 --size 128x128 -b jellyfish:duration=1",
       "ropsim capture gl --frame 5 --list -- glmark2 --size 128x128 -b pulsar:duration=1",
       "ropsim capture gl --apitrace app.trace --frame 10 -o app.trace.rop"}));
  return [o, sub]() { return run_capture_gl(*o, *sub); };
}

}  // namespace ropsim
