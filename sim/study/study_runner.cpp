#include "sim/study/study_runner.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <system_error>

#include "sim/fidelity/approximate/approximate.h"
#include "sim/fidelity/cycle/cycle_run.h"
#include "sim/fidelity/fidelity.h"
#include "sim/fidelity/run.h"
#include "sim/fidelity/sampled/livepoint_file.h"
#include "sim/image/image_io.h"
#include "sim/report/cycle_report.h"
#include "sim/report/report.h"
#include "sim/report/run_report.h"
#include "traces/capture/capture.h"
#include "traces/glcapture/gl_capture.h"
#include "util/errors.h"
#include "util/host_threads.h"
#include "util/output_file.h"
#include "util/progress.h"
#include "util/version.h"
#include "util/worker_pool.h"

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

int study_exit_status(const StudySummary& sum, size_t not_run) {
  int st = sum.failed || not_run ? kUserErrorStatus : 0;
  for (const auto& f : sum.failures) st = std::max(st, f.status);
  return st;
}

std::string count_of(size_t n, const char* noun) { return fmt::format("{} {}{}", n, noun, n == 1 ? "" : "s"); }

namespace {

// ------------------------------------------------------------------ failures

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
std::string recorded_form(const ErrorVerdict& v) { return v.status == kUserErrorStatus ? v.what : v.message(); }

/// The kind of a task's failure, and its error on one line (recorded_form).
/// Its exit status is the one rule's (util/errors.h); whether its host failed
/// is the study's own question (a plain rerun retries it).
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

// ------------------------------------------------------------------ tasks

struct Task {
  char kind;     ///< 'c': capture a mesh input, 'r': render a reference, 'p': run a point
  size_t index;  ///< the point (for 'c' and 'r': a point that names the capture or reference)
};

std::string read_file(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

fs::path point_dir(const std::string& dir, const StudyPoint& p) { return fs::path(dir) / "points" / p.hash; }
fs::path ref_path(const std::string& dir, const std::string& key) { return fs::path(dir) / "refs" / (key + ".exr"); }

fs::path capture_path(const std::string& dir, const std::string& key) {
  return fs::path(dir) / "traces" / (key + ".rtr");
}

/// Where a failed capture or reference records its error, by its key: the
/// points that need it (run by this process or by another executor's task)
/// record the same error as theirs.
fs::path capture_error_path(const std::string& dir, const std::string& key) {
  return fs::path(dir) / "traces" / (key + ".error");
}
fs::path ref_error_path(const std::string& dir, const std::string& key) {
  return fs::path(dir) / "refs" / (key + ".error");
}
/// A task whose host failed records its error here instead (host-error.txt
/// in a point's folder, <key>.host-error beside a capture or reference): it
/// is not the task's verdict, and a plain rerun runs it again.
fs::path host_error_path(const fs::path& error_path) {
  return error_path.parent_path() /
         (error_path.extension() == ".txt" ? "host-error.txt" : error_path.stem().string() + ".host-error");
}

/// The recorded error of a failed capture or reference, without its newline.
std::string recorded_error(const fs::path& f) {
  std::string e = read_file(f);
  while (!e.empty() && e.back() == '\n') e.pop_back();
  return e;
}

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
        } catch (const std::exception& e) {
          unusable = e.what();
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

// ------------------------------------------------------------------ database

/// "file:" URI of a path (RFC 3986 escapes for what SQLite's URI parser reads).
std::string sqlite_uri(const fs::path& p) {
  std::string u = "file:";
  for (unsigned char c : fs::absolute(p).lexically_normal().string())
    u += std::isalnum(c) || std::strchr("/-._~", c) ? std::string(1, char(c)) : fmt::format("%{:02X}", c);
  return u;
}

/// A point's row as a study's database records it.
struct RowState {
  std::string status, error;                    ///< "ok" / "failed", the error
  StudyFailure failure = StudyFailure::kInput;  ///< when failed
};

/// A declared point as the database records it (table `points`).
struct RecordedPoint {
  std::string hash, params;  ///< params: params_json().dump() ("" in a folder that did not record them)
};

class Db {
 public:
  enum class Mode { kWrite, kRead };
  /// kWrite: creates the tables (WAL journal while it writes; settle() ends
  /// it). kRead: read-only (SQLITE_OPEN_READONLY); a WAL database in a folder
  /// this process cannot write (read-only media: no -shm can be made) is
  /// opened immutable when no write-ahead log is left beside it.
  explicit Db(const std::string& path, Mode mode = Mode::kWrite) : path_(path) {
    if (mode == Mode::kRead) {
      open_read();
      if (!has_table("results")) fail("not a study's database (no table 'results')");
    } else {
      if (sqlite3_open(path.c_str(), &db_) != SQLITE_OK) fail(sqlite3_errmsg(db_));
      exec("PRAGMA journal_mode=WAL");
      exec("PRAGMA synchronous=NORMAL");
      exec(
          "CREATE TABLE IF NOT EXISTS results (point TEXT PRIMARY KEY, point_index INTEGER, status TEXT, error TEXT, "
          "failure TEXT, report TEXT)");
      exec("CREATE TABLE IF NOT EXISTS study (key TEXT PRIMARY KEY, value TEXT)");
      exec("CREATE TABLE IF NOT EXISTS points (point TEXT PRIMARY KEY, point_index INTEGER, params TEXT)");
    }
    sqlite3_stmt* st = prepare("SELECT name FROM pragma_table_info('results')");
    while (sqlite3_step(st) == SQLITE_ROW) columns_.insert(reinterpret_cast<const char*>(sqlite3_column_text(st, 0)));
    sqlite3_finalize(st);
    if (mode == Mode::kWrite && !columns_.count("failure")) {  // a database that predates the column
      exec("ALTER TABLE results ADD COLUMN failure TEXT");
      columns_.insert("failure");
    }
  }
  ~Db() { sqlite3_close(db_); }
  Db(const Db&) = delete;
  Db& operator=(const Db&) = delete;

  /// A writer that is done: the database back to a rollback journal, its
  /// write-ahead log folded in and removed, so that readers need no -shm file
  /// (a finished study reads from read-only media). Busy (a reader holds it):
  /// it stays in WAL until the next writer is done.
  void settle() { sqlite3_exec(db_, "PRAGMA journal_mode=DELETE", nullptr, nullptr, nullptr); }

  bool has_table(const std::string& name) {
    sqlite3_stmt* st = prepare("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?");
    sqlite3_bind_text(st, 1, name.c_str(), -1, SQLITE_TRANSIENT);
    const bool has = sqlite3_step(st) == SQLITE_ROW;
    sqlite3_finalize(st);
    return has;
  }
  /// A value of table `study` ("" when absent).
  std::string meta(const std::string& key) {
    if (!has_table("study")) return "";
    sqlite3_stmt* st = prepare("SELECT value FROM study WHERE key = ?");
    sqlite3_bind_text(st, 1, key.c_str(), -1, SQLITE_TRANSIENT);
    std::string v;
    if (sqlite3_step(st) == SQLITE_ROW && sqlite3_column_text(st, 0))
      v = reinterpret_cast<const char*>(sqlite3_column_text(st, 0));
    sqlite3_finalize(st);
    return v;
  }
  /// The points the folder's study declares (table `points`); `declared` is
  /// false for a database that did not record them: then the points it holds
  /// results of.
  std::vector<RecordedPoint> recorded_points(bool& declared) {
    std::vector<RecordedPoint> v;
    declared = has_table("points");
    if (declared) {
      sqlite3_stmt* st = prepare("SELECT point, params FROM points ORDER BY point_index");
      while (sqlite3_step(st) == SQLITE_ROW) v.push_back({text(st, 0), text(st, 1)});
      sqlite3_finalize(st);
      declared = !v.empty();
    }
    if (!declared) {
      sqlite3_stmt* st = prepare("SELECT point FROM results ORDER BY point_index");
      while (sqlite3_step(st) == SQLITE_ROW) v.push_back({text(st, 0), ""});
      sqlite3_finalize(st);
    }
    return v;
  }
  /// Records the study's identity: its name, file and points (table
  /// `points`), and the place of each point's row in its expansion.
  void record_points(const Study& s, const std::vector<StudyPoint>& points) {
    exec("BEGIN IMMEDIATE");
    exec("DELETE FROM points");
    for (const auto& p : points) {
      sqlite3_stmt* st = prepare("INSERT INTO points (point, point_index, params) VALUES (?, ?, ?)");
      const std::string params = p.params_json().dump();
      sqlite3_bind_text(st, 1, p.hash.c_str(), -1, SQLITE_TRANSIENT);
      sqlite3_bind_int64(st, 2, int64_t(p.index));
      sqlite3_bind_text(st, 3, params.c_str(), -1, SQLITE_TRANSIENT);
      step_done(st);
      st = prepare("UPDATE results SET point_index = ? WHERE point = ?");
      sqlite3_bind_int64(st, 1, int64_t(p.index));
      sqlite3_bind_text(st, 2, p.hash.c_str(), -1, SQLITE_TRANSIENT);
      step_done(st);
    }
    set_meta("name", s.name);
    set_meta("file", s.path);
    set_meta("points", std::to_string(points.size()));
    set_meta("ropsim", std::string(ropsim_version()) + " " + ropsim_commit());
    exec("COMMIT");
  }

  void exec(const std::string& sql) {
    char* err = nullptr;
    if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err) != SQLITE_OK) {
      const std::string e = err ? err : "?";
      sqlite3_free(err);
      fail(e);
    }
  }
  sqlite3_stmt* prepare(const std::string& sql) {
    sqlite3_stmt* st = nullptr;
    if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &st, nullptr) != SQLITE_OK) fail(sqlite3_errmsg(db_));
    return st;
  }
  /// The row of every point in the table, by hash. A failure of a database
  /// without the `failure` column is an input failure.
  std::map<std::string, RowState> statuses() {
    std::map<std::string, RowState> m;
    sqlite3_stmt* st = prepare("SELECT point, status, error, failure FROM results");
    while (sqlite3_step(st) == SQLITE_ROW)
      m[text(st, 0)] =
          RowState{text(st, 1), text(st, 2), text(st, 3) == "host" ? StudyFailure::kHost : StudyFailure::kInput};
    sqlite3_finalize(st);
    return m;
  }
  void set_meta(const std::string& k, const std::string& v) {
    sqlite3_stmt* st = prepare("INSERT OR REPLACE INTO study (key, value) VALUES (?, ?)");
    sqlite3_bind_text(st, 1, k.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_text(st, 2, v.c_str(), -1, SQLITE_TRANSIENT);
    step_done(st);
  }
  /// One row: every column a typed value; new columns are added as needed.
  void put_row(const std::vector<std::pair<std::string, nlohmann::ordered_json>>& row) {
    exec("BEGIN IMMEDIATE");
    for (const auto& [name, v] : row)
      if (!columns_.count(name)) {
        // A column first seen null (e.g. silicon.total.nand2_eq of a method without reference RTL) has no
        // type, so that the numbers of later points stay numbers (a TEXT column would store them as text).
        const char* type = v.is_null()                               ? ""
                           : v.is_number_integer() || v.is_boolean() ? "INTEGER"
                           : v.is_number()                           ? "REAL"
                                                                     : "TEXT";
        exec(fmt::format("ALTER TABLE results ADD COLUMN {} {}", quote(name), type));
        columns_.insert(name);
      }
    std::string cols, marks;
    for (const auto& [name, v] : row) {
      cols += (cols.empty() ? "" : ", ") + quote(name);
      marks += marks.empty() ? "?" : ", ?";
    }
    sqlite3_stmt* st = prepare("INSERT OR REPLACE INTO results (" + cols + ") VALUES (" + marks + ")");
    int i = 1;
    for (const auto& [name, v] : row) {
      if (v.is_null())
        sqlite3_bind_null(st, i);
      else if (v.is_boolean())
        sqlite3_bind_int64(st, i, v.get<bool>() ? 1 : 0);
      else if (v.is_number_unsigned())
        sqlite3_bind_int64(st, i, int64_t(v.get<uint64_t>()));
      else if (v.is_number_integer())
        sqlite3_bind_int64(st, i, v.get<int64_t>());
      else if (v.is_number())
        sqlite3_bind_double(st, i, v.get<double>());
      else {
        const std::string s = v.is_string() ? v.get<std::string>() : v.dump();
        sqlite3_bind_text(st, i, s.c_str(), -1, SQLITE_TRANSIENT);
      }
      ++i;
    }
    step_done(st);
    exec("COMMIT");
  }
  sqlite3* handle() { return db_; }

 private:
  static std::string text(sqlite3_stmt* st, int col) {
    const unsigned char* t = sqlite3_column_text(st, col);
    return t ? reinterpret_cast<const char*>(t) : "";
  }
  void open_read() {
    const auto probe = [&] {
      return sqlite3_exec(db_, "SELECT count(*) FROM sqlite_master", nullptr, nullptr, nullptr);
    };
    int rc = sqlite3_open_v2(path_.c_str(), &db_, SQLITE_OPEN_READONLY, nullptr);
    if (rc == SQLITE_OK) rc = probe();
    if (rc == SQLITE_OK) return;
    const std::string why = sqlite3_errmsg(db_);
    std::error_code ec;
    const fs::path wal = path_ + "-wal";
    const bool log_left = fs::exists(wal, ec) && fs::file_size(wal, ec) > 0;
    if (rc == SQLITE_CANTOPEN && !log_left && ::access(fs::path(path_).parent_path().c_str(), W_OK) != 0) {
      sqlite3_close(db_);
      db_ = nullptr;
      rc = sqlite3_open_v2((sqlite_uri(path_) + "?immutable=1").c_str(), &db_, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI,
                           nullptr);
      if (rc == SQLITE_OK) rc = probe();
      if (rc == SQLITE_OK) return;
    }
    fail(why);
  }
  static std::string quote(const std::string& n) {
    std::string q = "\"";
    for (char c : n) q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
  }
  void step_done(sqlite3_stmt* st) {
    const int rc = sqlite3_step(st);
    sqlite3_finalize(st);
    if (rc != SQLITE_DONE) fail(sqlite3_errmsg(db_));
  }
  [[noreturn]] void fail(const std::string& why) { throw UserError(path_ + ": " + why); }
  std::string path_;
  sqlite3* db_ = nullptr;
  std::set<std::string> columns_;
};

/// The report's scalar fields as columns, by their report path (arrays and
/// the long texts stay in the report JSON).
void flatten(const nlohmann::ordered_json& j, const std::string& at,
             std::vector<std::pair<std::string, nlohmann::ordered_json>>& out) {
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end(); ++it)
      flatten(it.value(), at.empty() ? it.key() : at + "." + it.key(), out);
  } else if (!j.is_array() && at != "command" && at != "hardware.resolved_toml") {
    out.emplace_back(at, j);
  }
}

/// A point's row: its result (status "ok" and its report) or its failure
/// (status "failed", the error and the kind of failure).
std::vector<std::pair<std::string, nlohmann::ordered_json>> row_of(const StudyPoint& p, const std::string& status,
                                                                   const std::string& error,
                                                                   const nlohmann::ordered_json* report,
                                                                   StudyFailure failure = StudyFailure::kInput) {
  std::vector<std::pair<std::string, nlohmann::ordered_json>> row = {
      {"point", p.hash}, {"point_index", p.index}, {"status", status}, {"error", error}};
  if (status != "ok") row.emplace_back("failure", to_string(failure));
  std::set<std::string> names = {"point", "point_index", "status", "error", "failure", "report"};
  const nlohmann::ordered_json params = p.params_json();
  for (auto it = params.begin(); it != params.end(); ++it) {
    row.emplace_back(it.key(), it.value());
    names.insert(it.key());
  }
  if (report) {
    row.emplace_back("report", report->dump());
    std::vector<std::pair<std::string, nlohmann::ordered_json>> m;
    flatten(*report, "", m);
    for (auto& [k, v] : m)
      if (names.insert(k).second) row.emplace_back(k, v);
  }
  return row;
}

/// What a point's folder holds.
enum class Outcome { kNone, kOk, kInputFailure, kHostFailure };

/// Records a finished point from its folder: its report, or its error (an
/// input error, error.txt, or its host's failure, host-error.txt).
Outcome record_from_folder(Db& db, const std::string& dir, const StudyPoint& p) {
  const fs::path pd = point_dir(dir, p);
  if (fs::exists(pd / "report.json")) {
    const nlohmann::ordered_json report = nlohmann::ordered_json::parse(read_file(pd / "report.json"));
    auto row = row_of(p, "ok", "", &report);
    std::string ref = fs::exists(pd / "reference.txt") ? read_file(pd / "reference.txt") : "";
    while (!ref.empty() && ref.back() == '\n') ref.pop_back();
    row.emplace_back("reference_key", ref);
    db.put_row(row);
    return Outcome::kOk;
  }
  for (const auto& [file, kind] :
       {std::pair{"error.txt", StudyFailure::kInput}, {"host-error.txt", StudyFailure::kHost}})
    if (fs::exists(pd / file)) {
      db.put_row(row_of(p, "failed", recorded_error(pd / file), nullptr, kind));
      return kind == StudyFailure::kHost ? Outcome::kHostFailure : Outcome::kInputFailure;
    }
  return Outcome::kNone;
}

/// Removes a point's recorded errors before it runs again.
void clear_point_errors(const std::string& dir, const StudyPoint& p) {
  fs::remove(point_dir(dir, p) / "error.txt");
  fs::remove(point_dir(dir, p) / "host-error.txt");
}

}  // namespace

std::string describe_point(const StudyPoint& p) {
  std::string s = p.hash + " (" + p.input;
  for (const auto& [k, v] : p.params) s += ", " + k + "=" + to_string(v);
  return s + ")";
}

namespace {
/// Folder -> the descriptor of its lock, kept until the process ends.
std::map<std::string, int>& held_folder_locks() {
  static std::map<std::string, int> held;
  return held;
}
/// In a forked worker: close the inherited lock descriptors (close only: an
/// unlock would release the parent's lock, which shares them), so that a
/// worker outliving a killed parent does not keep the folder locked.
void close_inherited_folder_locks() {
  for (const auto& [dir, fd] : held_folder_locks()) ::close(fd);
  held_folder_locks().clear();
}
}  // namespace

void hold_study_folder(const std::string& dir) {
  std::map<std::string, int>& held = held_folder_locks();
  const std::string key = fs::weakly_canonical(dir).string();
  if (held.count(key)) return;
  const std::string path = (fs::path(dir) / ".lock").string();
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) throw UserError(path + ": cannot open the study folder's lock: " + std::strerror(errno));
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int e = errno;
    ::close(fd);
    if (e == EWOULDBLOCK)
      throw UserError(dir +
                      ": another ropsim is running or collecting a study in this folder; wait for it to "
                      "finish, or use another --out");
    throw UserError(path + ": cannot lock the study folder: " + std::strerror(e));
  }
  held[key] = fd;
}

namespace {

/// The names in a study folder that hold its results (--force removes them;
/// nothing else in the folder is touched).
const char* const kResultNames[] = {"results.db", "results.db-wal", "results.db-shm", "results.db-journal",
                                    "study.toml", "points",         "refs",           "traces",
                                    "livepoints", "report",         "slurm"};

/// Removes a study folder's results (its lock held): each is first renamed
/// into DIR/.replaced-XXXXXX, the database first, then that folder is
/// removed, so that an interrupted removal leaves no old result beside the
/// new ones under the names the study reads. A .replaced- folder an
/// interrupted removal left is removed too.
void remove_study_results(const std::string& dir) {
  std::string tmpl = (fs::path(dir) / ".replaced-XXXXXX").string();
  if (!::mkdtemp(tmpl.data()))
    throw SystemError(dir + ": cannot replace the study's results: " + std::strerror(errno), errno);
  const fs::path trash = tmpl;
  for (const char* name : kResultNames) {
    std::error_code ec;
    const fs::path from = fs::path(dir) / name;
    if (!fs::exists(fs::symlink_status(from, ec))) continue;
    fs::rename(from, trash / name, ec);
    if (ec) throw UserError(from.string() + ": cannot remove the study's results: " + ec.message());
  }
  std::vector<fs::path> replaced;  // this removal's and any an interrupted one left
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().filename().string().rfind(".replaced-", 0) == 0 && e.is_directory() && !e.is_symlink())
      replaced.push_back(e.path());
  for (const auto& r : replaced) {
    std::error_code ec;
    fs::remove_all(r, ec);
    if (ec) throw UserError(r.string() + ": cannot remove the study's former results: " + ec.message());
  }
}

/// Checks that the study folder dir holds s (o.use), naming the folder and
/// the study recorded there when it does not. Returns true when its results
/// must be removed first (--force, whatever study they are of).
///
/// Two studies are the same when they have the same points, a point being
/// its hash: every parameter, the contents of the design files it names, the
/// reference settings and ropsim's version. The study's name, its file's
/// place and text beyond the points (comments, [slurm]) may change.
bool replaces_folder(Db& db, const Study& s, const std::vector<StudyPoint>& points, const StudyRunOptions& o) {
  bool declared = false;
  const std::vector<RecordedPoint> rec = db.recorded_points(declared);
  if (rec.empty()) return false;  // a new folder, or one that holds nothing yet
  if (o.use == StudyFolderUse::kReplace) return true;
  std::map<std::string, const StudyPoint*> now;
  std::map<std::string, const StudyPoint*> by_params;
  for (const auto& p : points) {
    now[p.hash] = &p;
    by_params[p.params_json().dump()] = &p;
  }
  std::vector<const RecordedPoint*> gone;  // recorded points that are not points of s
  for (const auto& r : rec)
    if (!now.count(r.hash)) gone.push_back(&r);
  const size_t kept = rec.size() - gone.size(), added = points.size() - kept;
  // A folder that did not declare its points holds the results of some:
  // they are the study's when they are among its points.
  if (gone.empty() && (added == 0 || !declared)) return false;
  const std::string name = db.meta("name"), file = db.meta("file");
  const std::string held = fmt::format("study {} ({}{})", name.empty() ? "?" : name, file.empty() ? "" : file + ", ",
                                       count_of(rec.size(), "point"));
  if (o.use == StudyFolderUse::kExtend) {
    if (gone.empty()) return false;
    const RecordedPoint& g = *gone.front();
    auto same = by_params.find(g.params);
    const std::string why =
        same != by_params.end()
            ? fmt::format(
                  "point {} has the parameters {} there but another identity here ({}): a design file it "
                  "names, the reference settings or ropsim's version changed",
                  g.hash, g.params, same->second->hash)
            : fmt::format("point {}{} is not a point of {}", g.hash, g.params.empty() ? "" : " " + g.params, s.path);
    throw UserError(
        fmt::format("{}: --extend keeps the points of the {} held there, but {} of them changed or "
                    "are gone: {}; use --force to replace the folder's results, or another --out",
                    o.out_dir, held, gone.size(), why));
  }
  // The same parameters throughout, another identity: most often another
  // ropsim (a point's identity includes the tool's version and commit).
  bool same_params = declared && rec.size() == points.size();
  for (const auto& r : rec) same_params = same_params && by_params.count(r.params);
  if (same_params) {
    const std::string made = db.meta("ropsim"), now_tool = std::string(ropsim_version()) + " " + ropsim_commit();
    throw UserError(fmt::format(
        "{}: holds the results of {}{}; {} has the same parameters but {} of its points have another identity "
        "({}a design file they name or the reference settings changed): use --force to run the study again, or "
        "another --out",
        o.out_dir, held, made.empty() ? "" : ", made by ropsim " + made, s.path, gone.size(),
        made.empty() || made == now_tool ? "ropsim's version, " : "this is ropsim " + now_tool + "; or "));
  }
  if (gone.empty())
    throw UserError(
        fmt::format("{}: holds the results of {}; {} (study {}) adds {} to them: use --extend to run "
                    "them, --force to replace the folder's results, or another --out",
                    o.out_dir, held, s.path, s.name, count_of(added, "point")));
  throw UserError(
      fmt::format("{}: holds the results of {}, not of {} (study {}, {}, {} of them in common): use "
                  "--force to replace the folder's results, or another --out",
                  o.out_dir, held, s.path, s.name, count_of(points.size(), "point"), kept));
}

/// A failed point in the summary.
void count_failure(StudySummary& sum, const StudyPoint& p, const std::string& error, StudyFailure kind) {
  ++sum.failed;
  if (kind == StudyFailure::kHost) ++sum.failed_host;
  sum.failures.push_back(StudyPointFailure{describe_point(p), error, kind, failure_status(error)});
}

}  // namespace

StudyPlan plan_study(const Study& s, const StudyRunOptions& o, StudySummary& sum) {
  const std::vector<StudyPoint> points = expand_study(s);
  StudyPlan plan;
  sum = StudySummary{};
  sum.points = points.size();
  std::error_code ec;
  fs::create_directories(o.out_dir, ec);
  if (ec) throw UserError(o.out_dir + ": cannot create the study folder: " + ec.message());
  hold_study_folder(o.out_dir);
  const std::string db_path = (fs::path(o.out_dir) / "results.db").string();
  if (fs::exists(db_path)) {
    bool replace = false;
    {
      Db db(db_path);
      replace = replaces_folder(db, s, points, o);
    }
    if (replace) remove_study_results(o.out_dir);
  }
  fs::create_directories(fs::path(o.out_dir) / "points", ec);
  if (!ec) fs::create_directories(fs::path(o.out_dir) / "refs", ec);
  if (!ec) fs::create_directories(fs::path(o.out_dir) / "traces", ec);
  if (ec) throw UserError(o.out_dir + ": cannot create the study folder: " + ec.message());
  write_text_output((fs::path(o.out_dir) / "study.toml").string(), read_file(s.path));
  std::map<std::string, size_t> ref_of, capture_of;  // key -> the first point naming it
  Db db(db_path);
  db.record_points(s, points);
  auto status = db.statuses();
  for (const auto& p : points) {
    auto it = status.find(p.hash);
    if (it != status.end() && it->second.status == "ok") {
      ++sum.reused;
      continue;
    }
    // The folder may hold a newer outcome than the row: a point a run killed
    // before recording it finished, or another executor's task ran it.
    const Outcome in_folder = record_from_folder(db, o.out_dir, p);
    if (in_folder == Outcome::kOk) {
      ++sum.reused;
      continue;
    }
    StudyFailure kind = in_folder == Outcome::kHostFailure ? StudyFailure::kHost : StudyFailure::kInput;
    std::string error =
        in_folder == Outcome::kNone
            ? ""
            : recorded_error(point_dir(o.out_dir, p) / (kind == StudyFailure::kHost ? "host-error.txt" : "error.txt"));
    if (in_folder == Outcome::kNone && it != status.end()) {  // the row's failure, its folder gone or cleared
      kind = it->second.failure;
      error = it->second.error;
    }
    const bool failed = in_folder != Outcome::kNone || it != status.end();
    // An input failure stays unless --retry-failed; a host failure runs again.
    if (failed && kind == StudyFailure::kInput && !o.retry_failed) {
      count_failure(sum, p, error, kind);
      continue;
    }
    clear_point_errors(o.out_dir, p);
    // A point the parameters already make impossible fails here.
    try {
      const ResolvedPoint r = resolve_point(s, p, o.out_dir);
      if (!r.capture_key.empty() && !fs::exists(capture_path(o.out_dir, r.capture_key)) &&
          capture_of.emplace(r.capture_key, p.index).second)
        plan.captures.push_back(p.index);
      if (!r.reference_key.empty() && !fs::exists(ref_path(o.out_dir, r.reference_key)) &&
          ref_of.emplace(r.reference_key, p.index).second)
        plan.references.push_back(p.index);
      plan.points.push_back(p.index);
    } catch (...) {
      const auto [k, e] = failure_of(std::current_exception());
      fs::create_directories(point_dir(o.out_dir, p));
      write_text_output((k == StudyFailure::kHost ? host_error_path(point_dir(o.out_dir, p) / "error.txt")
                                                  : point_dir(o.out_dir, p) / "error.txt")
                            .string(),
                        e + "\n");
      db.put_row(row_of(p, "failed", e, nullptr, k));
      count_failure(sum, p, e, k);
    }
  }
  db.settle();
  return plan;
}

namespace {

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

std::string describe_failures(const StudySummary& sum) {
  const size_t host = sum.failed_host, input = sum.failed - sum.failed_host;
  if (!sum.failed) return "0 failed";
  const char* input_rerun = input == 1 ? "--retry-failed reruns it" : "--retry-failed reruns them";
  const char* host_rerun = host == 1 ? "running the study again retries it" : "running the study again retries them";
  if (!host)
    return fmt::format("{} failed ({}; {})", input, input == 1 ? "an input error" : "input errors", input_rerun);
  if (!input)
    return fmt::format("{} failed ({}; {})", host, host == 1 ? "a host failure" : "host failures", host_rerun);
  return fmt::format("{} failed ({} input error{}, {}; {} host failure{}, {})", sum.failed, input,
                     input == 1 ? "" : "s", input_rerun, host, host == 1 ? "" : "s", host_rerun);
}

namespace {

/// A task in a worker process: "c N", "r N" or "p N" (a capture, a
/// reference, a point); answers "ok" or "fail KIND ERROR" (KIND: host or
/// input; the error on one line), the error also in the task's error file.
std::string serve_task(const Study& s, const std::vector<StudyPoint>& points, const std::string& dir,
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

/// A worker's reply (serve_task) as the task's result.
StudyTaskResult parse_reply(const std::string& line) {
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

}  // namespace

StudySummary run_study(const Study& s, const StudyRunOptions& o) {
  const std::vector<StudyPoint> points = expand_study(s);
  StudySummary sum;
  const StudyPlan plan = plan_study(s, o, sum);
  if (plan.points.empty()) return sum;
  std::map<std::string, size_t> ref_of, capture_of;  // key -> the point whose task makes it
  std::map<size_t, std::string> key_of, capkey_of;   // point -> its reference and capture keys
  for (size_t pi : plan.points) {
    const ResolvedPoint r = resolve_point(s, points[pi], o.out_dir);
    if (!r.reference_key.empty()) key_of[pi] = r.reference_key;
    if (!r.capture_key.empty()) capkey_of[pi] = r.capture_key;
  }
  for (size_t pi : plan.references) ref_of[key_of[pi]] = pi;
  for (size_t pi : plan.captures) capture_of[capkey_of[pi]] = pi;
  const std::vector<size_t>& todo = plan.points;

  // The work graph: every missing capture, then every missing reference,
  // then the points.
  std::deque<Task> caps, refs, runs;
  for (const auto& [key, pi] : capture_of) caps.push_back(Task{'c', pi});
  for (const auto& [key, pi] : ref_of) refs.push_back(Task{'r', pi});
  for (size_t pi : todo) runs.push_back(Task{'p', pi});
  std::map<std::string, StudyTaskResult> failed_refs, failed_caps;  // key -> how its task failed

  const size_t n_workers = std::max<size_t>(1, std::min<size_t>(o.jobs, caps.size() + refs.size() + runs.size()));
  WorkerPool pool(
      n_workers, [&](const std::string& task) { return serve_task(s, points, o.out_dir, task); },
      [n_workers] {
        close_inherited_folder_locks();
        // The cores are the workers' to share: each point's golden model gets its share.
        set_host_threads(std::max(1, host_threads() / int(n_workers)));
      });
  std::vector<std::optional<Task>> held(n_workers);  // each worker's task

  Db db((fs::path(o.out_dir) / "results.db").string());
  const auto t0 = std::chrono::steady_clock::now();
  size_t done_now = 0, total_now = runs.size();
  auto last_print = t0 - std::chrono::seconds(10);
  const bool tty = o.progress && isatty(fileno(stderr));
  auto progress = [&](bool final) {
    if (!o.progress) return;
    const auto now = std::chrono::steady_clock::now();
    if (!final && !tty && now - last_print < std::chrono::seconds(5)) return;
    last_print = now;
    const double el = std::chrono::duration<double>(now - t0).count();
    const size_t rem = total_now - done_now;
    const std::string eta =
        done_now && rem ? ", ETA " + Progress::format_duration(el / double(done_now) * double(rem)) : std::string();
    const size_t done = sum.reused + sum.ran + sum.failed;
    std::fprintf(stderr, "%sstudy %s: %zu of %zu points done (%.1f %%), %zu failed, %zu remaining, %s%s%s",
                 tty ? "\r" : "", s.name.c_str(), done, sum.points,
                 sum.points ? 100.0 * double(done) / double(sum.points) : 100.0, sum.failed, rem,
                 Progress::format_duration(el).c_str(), eta.c_str(), tty && !final ? "   " : "\n");
  };

  auto busy_with = [&](char kind) {
    for (const auto& h : held)
      if (h && h->kind == kind) return true;
    return false;
  };
  // Why task t cannot run: its capture (or, for a point, its reference)
  // failed; the failure is of that task's kind.
  auto broken = [&](const Task& t) -> std::optional<StudyTaskResult> {
    auto c = capkey_of.find(t.index);
    if (c != capkey_of.end())
      if (auto f = failed_caps.find(c->second); f != failed_caps.end()) {
        StudyTaskResult b = f->second;
        b.error = "its capture failed: " + b.error;
        return b;
      }
    auto k = key_of.find(t.index);
    if (t.kind == 'p' && k != key_of.end())
      if (auto f = failed_refs.find(k->second); f != failed_refs.end()) {
        StudyTaskResult b = f->second;
        b.error = "its reference failed: " + b.error;
        return b;
      }
    return std::nullopt;
  };
  auto record_failure = [&](const StudyPoint& p, const StudyTaskResult& res) {
    db.put_row(row_of(p, "failed", res.error, nullptr, res.failure));
    count_failure(sum, p, res.error, res.failure);
  };
  auto next_task = [&]() -> std::optional<Task> {
    if (!caps.empty()) {
      Task t = caps.front();
      caps.pop_front();
      return t;
    }
    // References wait for the captures, points for both.
    if (busy_with('c')) return std::nullopt;
    while (!refs.empty()) {
      Task t = refs.front();
      refs.pop_front();
      if (auto b = broken(t)) {
        failed_refs[key_of[t.index]] = *b;
        continue;
      }
      return t;
    }
    if (busy_with('r')) return std::nullopt;
    while (!runs.empty()) {
      Task t = runs.front();
      runs.pop_front();
      if (auto b = broken(t)) {
        const StudyPoint& p = points[t.index];
        fs::path f = point_dir(o.out_dir, p) / "error.txt";
        if (b->failure == StudyFailure::kHost) f = host_error_path(f);
        try {
          fs::create_directories(f.parent_path());
          write_text_output(f.string(), b->error + "\n");
        } catch (...) {
          if (b->failure != StudyFailure::kHost) throw;  // an input error must be in the folder
        }
        record_failure(p, *b);
        ++done_now;
        continue;
      }
      return t;
    }
    return std::nullopt;
  };
  auto dispatch = [&]() {
    for (size_t w = 0; w < pool.size(); ++w)
      if (pool.idle(w))
        if (auto t = next_task()) {
          pool.send(w, fmt::format("{} {}", t->kind, t->index));
          held[w] = t;
        }
  };
  auto finish = [&](const Task& t, const StudyTaskResult& res) {
    const StudyPoint& p = points[t.index];
    if (t.kind == 'c') {
      if (!res.ok) failed_caps[capkey_of[t.index]] = res;
      return;
    }
    if (t.kind == 'r') {
      if (!res.ok) failed_refs[key_of[t.index]] = res;
      return;
    }
    ++done_now;
    if (res.ok && record_from_folder(db, o.out_dir, p) == Outcome::kOk) {
      ++sum.ran;
    } else if (res.ok) {
      record_failure(p, StudyTaskResult{false, StudyFailure::kHost,
                                        "its worker said done, but its folder holds no "
                                        "report.json"});
    } else {
      record_failure(p, res);
    }
    progress(false);
  };

  for (dispatch(); pool.any_busy(); dispatch()) {
    const WorkerPool::Reply r = pool.next();
    const Task t = *held[r.worker];
    held[r.worker].reset();
    if (r.kind == WorkerPool::Reply::Kind::kDied)  // a host failure: its task fails, the others go on
      finish(t, StudyTaskResult{
                    false, StudyFailure::kHost,
                    "the worker running it " + std::string(r.text.rfind("killed", 0) == 0 ? "was " : "") + r.text});
    else if (r.kind == WorkerPool::Reply::Kind::kFailed)  // serve_task itself failed
      finish(t, StudyTaskResult{false, StudyFailure::kInput, recorded_form(ErrorVerdict{r.status, r.text})});
    else
      finish(t, parse_reply(r.text));
  }
  pool.close();
  // Points a dead worker left (no worker remained to run them).
  while (!runs.empty()) {
    const StudyPoint& p = points[runs.front().index];
    runs.pop_front();
    record_failure(p, StudyTaskResult{false, StudyFailure::kHost, "no worker process was left to run it"});
  }
  db.settle();
  progress(true);
  return sum;
}

std::string study_file_of(const std::string& dir) {
  const fs::path db_path = fs::path(dir) / "results.db";
  if (!fs::exists(db_path)) throw UserError(dir + ": not a study folder (no results.db)");
  const std::string file = Db(db_path.string(), Db::Mode::kRead).meta("file");
  if (file.empty()) throw UserError(dir + ": the database does not name its study file");
  return file;
}

StudyExport export_study_csv(const std::string& dir, const std::string& csv_path) {
  const fs::path db_path = fs::path(dir) / "results.db";
  if (!fs::exists(db_path)) throw UserError(dir + ": not a study folder (no results.db)");
  Db db(db_path.string(), Db::Mode::kRead);
  StudyExport ex;
  ex.study = db.meta("name");
  sqlite3_stmt* st = db.prepare("SELECT * FROM results ORDER BY point_index");
  const int n = sqlite3_column_count(st);
  auto csv = [](const std::string& s) {
    if (s.find_first_of(",\"\n") == std::string::npos) return s;
    std::string q = "\"";
    for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
  };
  std::string out;
  std::vector<int> cols;
  for (int c = 0; c < n; ++c)
    if (std::string(sqlite3_column_name(st, c)) != "report") cols.push_back(c);
  for (size_t i = 0; i < cols.size(); ++i) out += (i ? "," : "") + csv(sqlite3_column_name(st, cols[i]));
  out += "\n";
  ex.columns = cols.size();
  int status_col = -1;
  for (int c = 0; c < n; ++c)
    if (std::string(sqlite3_column_name(st, c)) == "status") status_col = c;
  while (sqlite3_step(st) == SQLITE_ROW) {
    ++ex.rows;
    if (status_col >= 0 && sqlite3_column_text(st, status_col))
      ++(std::string(reinterpret_cast<const char*>(sqlite3_column_text(st, status_col))) == "ok" ? ex.ok : ex.failed);
    for (size_t i = 0; i < cols.size(); ++i) {
      const int c = cols[i];
      std::string v;
      switch (sqlite3_column_type(st, c)) {
        case SQLITE_NULL:
          break;
        case SQLITE_INTEGER:
          v = std::to_string(sqlite3_column_int64(st, c));
          break;
        case SQLITE_FLOAT:
          v = fmt::format("{}", sqlite3_column_double(st, c));
          break;
        default:
          v = reinterpret_cast<const char*>(sqlite3_column_text(st, c));
      }
      out += (i ? "," : "") + csv(v);
    }
    out += "\n";
  }
  sqlite3_finalize(st);
  write_text_output(csv_path, out, true);
  return ex;
}

}  // namespace ropsim
