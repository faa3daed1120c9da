#include "sim/study/study_tasks.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>
#include <system_error>
#include <tuple>

#include "sim/fidelity/fidelity.h"
#include "sim/fidelity/run.h"
#include "sim/fidelity/sampled/livepoint_file.h"
#include "sim/image/image_io.h"
#include "sim/report/cycle_report.h"
#include "sim/report/report.h"
#include "sim/report/run_report.h"
#include "sim/study/study_folder.h"
#include "traces/capture/capture.h"
#include "traces/glcapture/gl_capture.h"
#include "util/output_file.h"

namespace fs = std::filesystem;

namespace ropsim {

namespace {
/// How a broken invariant's recorded error begins (ErrorVerdict::message).
constexpr const char* kInternalPrefix = "internal error: ";
}  // namespace

const char* to_string(StudyFailure f) { return f == StudyFailure::kHost ? "host" : "input"; }

int failure_status(const std::string& error) {
  return error.rfind(kInternalPrefix, 0) == 0 ? kInternalErrorStatus : kUserErrorStatus;
}

std::string broken_invariant(const std::string& error) {
  if (failure_status(error) != kInternalErrorStatus) return error;
  std::string w = error.substr(std::strlen(kInternalPrefix));
  const std::string tail = ": please report it";
  if (w.size() >= tail.size() && w.compare(w.size() - tail.size(), tail.size(), tail) == 0)
    w.resize(w.size() - tail.size());
  return w;
}

namespace {

/// A failure the host caused that no errno names: a task's capture or
/// reference missing (its task ended without a result), a worker killed.
class HostFailure : public UserError {
 public:
  using UserError::UserError;
};

/// The system errors that say the host, not the point, failed.
bool host_errno(int e) {
  switch (e) {
    case ENOSPC:
    case EDQUOT:
    case EIO:
    case EFBIG:
    case ENOMEM:
    case ENFILE:
    case EMFILE:
    case EROFS:
    case ESTALE:
      return true;
    default:
      return false;
  }
}

/// A classified error as a study records it (failure_status).

}  // namespace

std::string recorded_form(const ErrorVerdict& v) { return v.status == kUserErrorStatus ? v.what : v.message(); }

std::pair<StudyFailure, std::string> failure_of(const std::exception_ptr& e) {
  const ErrorVerdict v = classify_error(e);
  StudyFailure kind = StudyFailure::kInput;
  try {
    std::rethrow_exception(e);
  } catch (const HostFailure&) {
    kind = StudyFailure::kHost;
  } catch (const SystemError& x) {
    kind = host_errno(x.error_number()) ? StudyFailure::kHost : StudyFailure::kInput;
  } catch (const std::system_error& x) {  // std::filesystem_error among them
    const bool os = x.code().category() == std::system_category() || x.code().category() == std::generic_category();
    kind = os && host_errno(x.code().value()) ? StudyFailure::kHost : StudyFailure::kInput;
  } catch (const std::bad_alloc&) {
    kind = StudyFailure::kHost;
  } catch (...) {
  }
  return {kind, recorded_form(v)};
}

namespace {

/// Throws the reason a task that needs r's capture (and, when with_reference,
/// its reference) cannot run: it failed (its recorded error: an input
/// failure, or a HostFailure when its host failed) or is missing (a
/// HostFailure: its task ended without a result).
void require_inputs(const ResolvedPoint& r, const std::string& dir, bool with_reference) {
  auto require = [](const fs::path& made, const fs::path& error, const char* what) {
    if (fs::exists(made)) return;
    if (fs::exists(error)) {
      const std::string e = recorded_error(error);
      if (failure_status(e) == kInternalErrorStatus)  // a bug, whichever task met it
        throw InternalError(std::string("its ") + what + " failed: " + broken_invariant(e));
      throw UserError(std::string("its ") + what + " failed: " + e);
    }
    if (fs::exists(host_error_path(error)))
      throw HostFailure(std::string("its ") + what + " failed: " + recorded_error(host_error_path(error)));
    throw HostFailure(std::string("its ") + what + " " + made.string() + " is missing");
  };
  if (!r.capture_key.empty())
    require(capture_path(dir, r.capture_key), capture_error_path(dir, r.capture_key), "capture");
  if (with_reference && !r.reference_key.empty())
    require(ref_path(dir, r.reference_key), ref_error_path(dir, r.reference_key), "reference");
}

/// The capture of a point's mesh or application input.
void capture_input(const Study& s, const StudyPoint& p, const std::string& dir) {
  const ResolvedPoint r = resolve_point(s, p, dir);
  if (!r.capture_app.empty()) {
    const AppEntry e = load_app_entry(r.capture_app, r.capture_app_overrides);
    GlCaptureRequest q;
    q.app = app_command(e);
    q.frame = e.frame;
    q.spp = e.spp;
    q.width = e.width;
    q.height = e.height;
    q.target = e.target;
    q.timeout = e.timeout;
    q.what = e.path;
    q.package = e.package;
    q.out = capture_path(dir, r.capture_key).string();
    run_gl_capture(q);
  } else {
    capture_to_file(load_scene_file(r.capture_scene, r.capture_overrides), capture_path(dir, r.capture_key).string());
  }
  fs::remove(capture_error_path(dir, r.capture_key));  // an earlier attempt's
  fs::remove(host_error_path(capture_error_path(dir, r.capture_key)));
}

/// The reference of a point: the A-buffer on its reference input.
void render_reference(const Study& s, const StudyPoint& p, const std::string& dir) {
  const ResolvedPoint r = resolve_point(s, p, dir);
  require_inputs(r, dir, false);
  MethodConfig m = r.method;
  m.method = Method::kReference;
  const FunctionalRun run = run_functional(r.reference_input, m);
  // The PNG first: the EXR's presence means the reference is done.
  write_image(run.image, (fs::path(dir) / "refs" / (r.reference_key + ".png")).string());
  write_image(run.image, ref_path(dir, r.reference_key).string());
  fs::remove(ref_error_path(dir, r.reference_key));  // an earlier attempt's
  fs::remove(host_error_path(ref_error_path(dir, r.reference_key)));
}

/// Throws UserError unless lib is the library of r: recorded from its input
/// (the digest: a trace's bytes, a scene's fragments at its spp), with its
/// method and numerics (the checks of `run --livepoints`) and its sampling.
/// with_input false: the input was checked already (the library a worker
/// holds, for a point of the same input).
void check_point_library(const LivePoints& lib, const std::string& path, const ResolvedPoint& r,
                         bool with_input = true) {
  if (with_input) check_library_input(lib, path, r.input);
  check_library_method(lib, path, r.method);
  check_library_sampling(lib, path, r.sampling);
}

/// What names a point's input for the library a worker holds: its
/// description, resolution and repeat count.
std::string input_name(const InputSpec& in) {
  return fmt::format("{} {}x{} spp {} seed {} repeat {}", in.describe(), in.scene.width, in.scene.height, in.scene.spp,
                     in.scene.seed, in.repeat);
}

/// A sampled point's live-point library: the one this worker read last, or
/// the study's DIR/livepoints/<key>.rlp, or recorded now and written there
/// (all or nothing: write_livepoints). Each is checked against the point
/// (check_point_library). The folder is a cache: a library there that does
/// not read or is not the point's is recorded again in its place, and
/// `rebuilt` says why. A lock on <key>.lock makes the workers (and the
/// executors' tasks) that need one library record it once. seconds: the
/// time this call took.
const LivePoints& point_library(const ResolvedPoint& r, const std::string& dir, double& seconds, std::string& rebuilt) {
  static std::string held_key, held_input;  // the library held, and the input it was checked against
  static std::unique_ptr<LivePoints> held;
  const auto t0 = std::chrono::steady_clock::now();
  const fs::path folder = fs::path(dir) / "livepoints";
  const fs::path lib = folder / (r.livepoints_key + ".rlp"), lock = folder / (r.livepoints_key + ".lock");
  if (held && held_key == r.livepoints_key) {
    check_point_library(*held, lib.string(), r, held_input != input_name(r.input));
    held_input = input_name(r.input);
  } else {
    held.reset();
    fs::create_directories(folder);
    const int fd = ::open(lock.c_str(), O_CREAT | O_RDWR | O_CLOEXEC, 0644);
    if (fd < 0) throw SystemError(lock.string() + ": " + std::strerror(errno), errno);
    while (::flock(fd, LOCK_EX) != 0 && errno == EINTR) {
    }
    try {
      std::string unusable;  // why the cached library cannot serve
      if (fs::exists(lib)) {
        try {
          auto cached = std::make_unique<LivePoints>(read_livepoints(lib.string()));
          check_point_library(*cached, lib.string(), r);
          held = std::move(cached);
        } catch (const std::bad_alloc&) {
          throw;
        } catch (const SystemError& e) {
          if (host_errno(e.error_number())) throw;  // the file may be sound: this host could not read it
          unusable = e.what();
        } catch (...) {
          // A library that does not read or is not the point's is recorded
          // again; a broken invariant is the point's failure, not the cache's.
          const ErrorVerdict v = classify_current_exception();
          if (v.status != kUserErrorStatus) throw;
          unusable = v.what;
        }
      }
      if (!held) {
        auto made = std::make_unique<LivePoints>(record_livepoints(r.input, r.method, r.sampling));
        try {
          write_livepoints(lib.string(), *made);
        } catch (const SystemError& e) {
          if (unusable.empty()) throw;
          throw SystemError(lib.string() + ": the cached library is unusable (" + unusable +
                                ") and could not be written again: " + e.what() + "; remove it and run the study again",
                            e.error_number());
        }
        if (!unusable.empty()) rebuilt = "recorded again in place of a cached library that was unusable: " + unusable;
        held = std::move(made);
      }
    } catch (...) {
      ::close(fd);  // releases the lock
      throw;
    }
    ::close(fd);
    held_key = r.livepoints_key;
    held_input = input_name(r.input);
  }
  seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return *held;
}

/// One point: its run, its report (with the metrics against the reference)
/// and its folder. report.json is written last: its presence means done.
void run_point(const Study& s, const StudyPoint& p, const std::string& dir) {
  const fs::path pd = point_dir(dir, p);
  fs::create_directories(pd);
  write_text_output((pd / "params.json").string(), p.params_json().dump(2) + "\n");
  const ResolvedPoint r = resolve_point(s, p, dir);
  require_inputs(r, dir, true);
  std::optional<Image> reference;
  if (!r.reference_key.empty()) {
    reference = read_image(ref_path(dir, r.reference_key).string());
    write_text_output((pd / "reference.txt").string(), r.reference_key + "\n");
  }
  ReportContext ctx{
      "ropsim study run " + s.path + " (point " + p.hash + ")", r.input, r.method, {}, {}, frame_of(r.input)};
  RunRequest req;
  req.fidelity = r.fidelity;
  req.input = r.input;
  req.method = r.method;
  req.hw = r.hw;
  std::string note;
  if (r.timed()) write_text_output((pd / "design.toml").string(), hw_config_to_toml(r.hw));
  if (r.fidelity == Fidelity::kSampled) {
    std::string rebuilt;
    req.library = &point_library(r, dir, req.from.seconds, rebuilt);
    req.from.path = (fs::path(dir) / "livepoints" / (r.livepoints_key + ".rlp")).string();
    if (!rebuilt.empty()) {
      // The point's log and the run's standard error say so.
      note = "live-point library " + req.from.path + ": " + rebuilt + "\n";
      std::fprintf(stderr, "ropsim: study %s: %s", s.name.c_str(), note.c_str());
    }
  }
  if (!r.timed()) ctx.design = rtl_design_of(r.hw);  // a functional point's silicon cost: the built-in design
  RunResult run = run_fidelity(req);
  run.set_reference(std::move(reference));
  const nlohmann::ordered_json report = run_report(ctx, run);
  const std::string summary = run_summary(ctx, run);
  const Image& image = run.image();
  if (s.save_images) write_image(image, (pd / "image.png").string());
  write_text_output((pd / "log.txt").string(), note + summary);
  write_text_output((pd / "report.json").string(), report.dump(2) + "\n");
}

/// run_study_task on points already expanded (a worker runs many tasks).
StudyTaskResult run_task(const Study& s, const std::vector<StudyPoint>& points, char kind, size_t point_index,
                         const std::string& dir) {
  if (point_index >= points.size()) throw UserError(fmt::format("{}: no point {}", s.path, point_index));
  if (kind != 'c' && kind != 'r' && kind != 'p')
    throw UserError(std::string("study task: unknown kind ") + kind + " (c, r or p)");
  const StudyPoint& p = points[point_index];
  StudyTaskResult res;
  try {
    if (kind == 'c')
      capture_input(s, p, dir);
    else if (kind == 'r')
      render_reference(s, p, dir);
    else {
      test_hook_internal_error("study-point");  // tests/test_errors.cpp
      run_point(s, p, dir);
    }
    res.ok = true;
    return res;
  } catch (...) {
    std::tie(res.failure, res.error) = failure_of(std::current_exception());
  }
  // The error, where the points that need the task (and a later plan) read
  // it; on a full disk it may not get there, and the caller has it.
  try {
    fs::path f = point_dir(dir, p) / "error.txt";
    if (kind == 'c' || kind == 'r') {
      const ResolvedPoint r = resolve_point(s, p, dir);  // planned, so it resolves
      const std::string& key = kind == 'c' ? r.capture_key : r.reference_key;
      const std::string name = key.empty() ? p.hash : key;  // a task the point does not need
      f = kind == 'c' ? capture_error_path(dir, name) : ref_error_path(dir, name);
    }
    if (res.failure == StudyFailure::kHost) f = host_error_path(f);
    fs::create_directories(f.parent_path());
    write_text_output(f.string(), res.error + "\n");
    res.recorded = true;
  } catch (...) {
  }
  return res;
}

}  // namespace

StudyTaskResult run_study_task(const Study& s, char kind, size_t point_index, const std::string& dir) {
  return run_task(s, expand_study(s), kind, point_index, dir);
}

std::string serve_study_task(const Study& s, const std::vector<StudyPoint>& points, const std::string& dir,
                             const std::string& task) {
  char kind = 0;
  size_t index = 0;
  std::istringstream(task) >> kind >> index;
  StudyTaskResult res;
  try {
    res = run_task(s, points, kind, index, dir);
  } catch (...) {
    std::tie(res.failure, res.error) = failure_of(std::current_exception());
  }
  return res.ok ? std::string("ok") : fmt::format("fail {} {}", to_string(res.failure), res.error);
}

StudyTaskResult parse_task_reply(const std::string& line) {
  StudyTaskResult res;
  std::istringstream in(line);
  std::string verdict, failure;
  in >> verdict;
  res.ok = verdict == "ok";
  if (res.ok) return res;
  in >> failure;
  res.failure = failure == "host" ? StudyFailure::kHost : StudyFailure::kInput;
  std::getline(in >> std::ws, res.error);
  if (res.error.empty()) res.error = "the worker gave no reason";
  return res;
}

}  // namespace ropsim
