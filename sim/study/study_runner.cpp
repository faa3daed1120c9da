#include "study_runner.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <poll.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/file.h>
#include <sys/wait.h>
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

#include "approximate.h"
#include "capture.h"
#include "cycle_report.h"
#include "cycle_run.h"
#include "errors.h"
#include "host_threads.h"
#include "image_io.h"
#include "livepoint_file.h"
#include "output_file.h"
#include "progress.h"
#include "report.h"

namespace fs = std::filesystem;

namespace ropsim {

namespace {

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

/// The recorded error of a failed capture or reference, without its newline.
std::string recorded_error(const fs::path& f) {
  std::string e = read_file(f);
  while (!e.empty() && e.back() == '\n') e.pop_back();
  return e;
}

/// Throws the reason a task that needs r's capture (and, when with_reference,
/// its reference) cannot run: it failed (its recorded error) or is missing.
void require_inputs(const ResolvedPoint& r, const std::string& dir, bool with_reference) {
  if (!r.capture_key.empty() && !fs::exists(capture_path(dir, r.capture_key))) {
    const fs::path e = capture_error_path(dir, r.capture_key);
    throw UserError(fs::exists(e) ? "its capture failed: " + recorded_error(e)
                                  : "its capture " + capture_path(dir, r.capture_key).string() + " is missing");
  }
  if (with_reference && !r.reference_key.empty() && !fs::exists(ref_path(dir, r.reference_key))) {
    const fs::path e = ref_error_path(dir, r.reference_key);
    throw UserError(fs::exists(e) ? "its reference failed: " + recorded_error(e)
                                  : "its reference " + ref_path(dir, r.reference_key).string() + " is missing");
  }
}

/// The capture of a point's mesh input.
void capture_input(const Study& s, const StudyPoint& p, const std::string& dir) {
  const ResolvedPoint r = resolve_point(s, p, dir);
  capture_to_file(load_scene_file(r.capture_scene, r.capture_overrides), capture_path(dir, r.capture_key).string());
  fs::remove(capture_error_path(dir, r.capture_key));  // an earlier attempt's
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
}

/// A sampled point's live-point library: the one this worker read last, or
/// the study's DIR/livepoints/<key>.rlp, or recorded now and written there.
/// A lock on <key>.lock makes the workers (and the executors' tasks) that
/// need one library record it once. seconds: the time this call took.
const LivePoints& point_library(const ResolvedPoint& r, const std::string& dir, double& seconds) {
  static std::string held_key;
  static std::unique_ptr<LivePoints> held;
  const auto t0 = std::chrono::steady_clock::now();
  if (!held || held_key != r.livepoints_key) {
    held.reset();
    const fs::path folder = fs::path(dir) / "livepoints";
    fs::create_directories(folder);
    const fs::path lib = folder / (r.livepoints_key + ".rlp"), lock = folder / (r.livepoints_key + ".lock");
    const int fd = ::open(lock.c_str(), O_CREAT | O_RDWR | O_CLOEXEC, 0644);
    if (fd < 0) throw UserError(lock.string() + ": " + std::strerror(errno));
    while (::flock(fd, LOCK_EX) != 0 && errno == EINTR) {
    }
    try {
      if (fs::exists(lib)) {
        held = std::make_unique<LivePoints>(read_livepoints(lib.string()));
      } else {
        held = std::make_unique<LivePoints>(record_livepoints(r.input, r.method, r.sampling));
        write_livepoints(lib.string(), *held);
      }
    } catch (...) {
      ::close(fd);  // releases the lock
      throw;
    }
    ::close(fd);
    held_key = r.livepoints_key;
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
  ReportContext ctx{"ropsim study run " + s.path + " (point " + p.hash + ")", r.input, r.method, {}, {}};
  nlohmann::ordered_json report;
  std::string summary;
  Image image;
  if (r.fidelity == "sampled") {
    write_text_output((pd / "design.toml").string(), hw_config_to_toml(r.hw));
    const auto t0 = std::chrono::steady_clock::now();
    LibrarySource from;
    const LivePoints& lib = point_library(r, dir, from.seconds);
    from.path = (fs::path(dir) / "livepoints" / (r.livepoints_key + ".rlp")).string();
    const SampledRun run = run_sampled(lib, r.hw, 1);
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    report = sampled_report(ctx, lib, run, r.hw, wall, from, reference);
    summary = sampled_summary(ctx, lib, run, r.hw, wall, from, reference);
    image = lib.image;
  } else if (r.fidelity == "approximate") {
    write_text_output((pd / "design.toml").string(), hw_config_to_toml(r.hw));
    ApproxRun run = run_approximate(r.input, r.method, r.hw);
    report = approximate_report(ctx, run, reference);
    summary = approximate_summary(ctx, run, reference);
    image = std::move(run.image);
  } else if (r.timed()) {
    write_text_output((pd / "design.toml").string(), hw_config_to_toml(r.hw));
    CycleRun run = run_cycle(r.input, r.method, r.hw);
    report = cycle_report(ctx, run, reference);
    summary = cycle_summary(ctx, run, reference);
    image = std::move(run.image);
  } else {
    FunctionalRun run = run_functional(r.input, r.method);
    run.reference = reference;
    ctx.design = rtl_design_of(r.hw);  // a functional point's silicon cost: the built-in design
    report = functional_report(ctx, run);
    summary = functional_summary(ctx, run);
    image = std::move(run.image);
  }
  if (s.save_images) write_image(image, (pd / "image.png").string());
  write_text_output((pd / "log.txt").string(), summary);
  write_text_output((pd / "report.json").string(), report.dump(2) + "\n");
}

/// A worker process: reads tasks ("r N" or "p N") from in_fd, answers
/// "N ok" or "N fail" on out_fd; the error goes to the task's error file.
// ------------------------------------------------------------------ database

class Db {
 public:
  explicit Db(const std::string& path) : path_(path) {
    if (sqlite3_open(path.c_str(), &db_) != SQLITE_OK) fail("cannot open");
    exec("PRAGMA journal_mode=WAL");
    exec("PRAGMA synchronous=NORMAL");
    exec(
        "CREATE TABLE IF NOT EXISTS results (point TEXT PRIMARY KEY, point_index INTEGER, status TEXT, error TEXT, "
        "report TEXT)");
    exec("CREATE TABLE IF NOT EXISTS study (key TEXT PRIMARY KEY, value TEXT)");
    sqlite3_stmt* st = prepare("SELECT name FROM pragma_table_info('results')");
    while (sqlite3_step(st) == SQLITE_ROW) columns_.insert(reinterpret_cast<const char*>(sqlite3_column_text(st, 0)));
    sqlite3_finalize(st);
  }
  ~Db() { sqlite3_close(db_); }
  Db(const Db&) = delete;
  Db& operator=(const Db&) = delete;

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
  /// status of every point in the table: hash -> "ok" / "failed".
  std::map<std::string, std::string> statuses() {
    std::map<std::string, std::string> m;
    sqlite3_stmt* st = prepare("SELECT point, status FROM results");
    while (sqlite3_step(st) == SQLITE_ROW)
      m[reinterpret_cast<const char*>(sqlite3_column_text(st, 0))] =
          reinterpret_cast<const char*>(sqlite3_column_text(st, 1));
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

std::vector<std::pair<std::string, nlohmann::ordered_json>> row_of(const StudyPoint& p, const std::string& status,
                                                                   const std::string& error,
                                                                   const nlohmann::ordered_json* report) {
  std::vector<std::pair<std::string, nlohmann::ordered_json>> row = {
      {"point", p.hash}, {"point_index", p.index}, {"status", status}, {"error", error}};
  std::set<std::string> names = {"point", "point_index", "status", "error", "report"};
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

/// Records a finished point from its folder: its report, or its error.
bool record_from_folder(Db& db, const std::string& dir, const StudyPoint& p) {
  const fs::path pd = point_dir(dir, p);
  if (fs::exists(pd / "report.json")) {
    const nlohmann::ordered_json report = nlohmann::ordered_json::parse(read_file(pd / "report.json"));
    auto row = row_of(p, "ok", "", &report);
    std::string ref = fs::exists(pd / "reference.txt") ? read_file(pd / "reference.txt") : "";
    while (!ref.empty() && ref.back() == '\n') ref.pop_back();
    row.emplace_back("reference_key", ref);
    db.put_row(row);
    return true;
  }
  if (fs::exists(pd / "error.txt")) {
    std::string e = read_file(pd / "error.txt");
    while (!e.empty() && e.back() == '\n') e.pop_back();
    db.put_row(row_of(p, "failed", e, nullptr));
    return true;
  }
  return false;
}

struct Worker {
  pid_t pid = -1;
  int to = -1, from = -1;
  std::string buf;
  std::optional<Task> busy;
};

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

StudyPlan plan_study(const Study& s, const StudyRunOptions& o, StudySummary& sum) {
  const std::vector<StudyPoint> points = expand_study(s);
  StudyPlan plan;
  sum = StudySummary{};
  sum.points = points.size();
  std::error_code ec;
  fs::create_directories(fs::path(o.out_dir) / "points", ec);
  if (!ec) fs::create_directories(fs::path(o.out_dir) / "refs", ec);
  if (!ec) fs::create_directories(fs::path(o.out_dir) / "traces", ec);
  if (ec) throw UserError(o.out_dir + ": cannot create the study folder: " + ec.message());
  hold_study_folder(o.out_dir);
  write_text_output((fs::path(o.out_dir) / "study.toml").string(), read_file(s.path));
  std::map<std::string, size_t> ref_of, capture_of;  // key -> the first point naming it
  Db db((fs::path(o.out_dir) / "results.db").string());
  db.set_meta("name", s.name);
  db.set_meta("file", s.path);
  db.set_meta("points", std::to_string(points.size()));
  auto status = db.statuses();
  for (const auto& p : points) {
    auto it = status.find(p.hash);
    const bool failed = it != status.end() && it->second != "ok";
    if (it != status.end() && !(failed && o.retry_failed)) {
      // A failed point retried by another executor's task (study run
      // --executor slurm --retry-failed) holds its new result or error.
      if (failed && record_from_folder(db, o.out_dir, p) && fs::exists(point_dir(o.out_dir, p) / "report.json")) {
        ++sum.reused;
        continue;
      }
      ++(failed ? sum.failed : sum.reused);
      if (failed) sum.failures.emplace_back(describe_point(p), "(recorded before)");
      continue;
    }
    if (failed) fs::remove(point_dir(o.out_dir, p) / "error.txt");
    // A point finished by a run that was killed before recording it, or by
    // another executor's task.
    if (!failed && record_from_folder(db, o.out_dir, p)) {
      if (fs::exists(point_dir(o.out_dir, p) / "report.json")) {
        ++sum.reused;
      } else {
        ++sum.failed;
        sum.failures.emplace_back(describe_point(p), recorded_error(point_dir(o.out_dir, p) / "error.txt"));
      }
      continue;
    }
    fs::remove(point_dir(o.out_dir, p) / "error.txt");
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
    } catch (const std::exception& e) {
      fs::create_directories(point_dir(o.out_dir, p));
      write_text_output((point_dir(o.out_dir, p) / "error.txt").string(), std::string(e.what()) + "\n");
      db.put_row(row_of(p, "failed", e.what(), nullptr));
      ++sum.failed;
      sum.failures.emplace_back(describe_point(p), e.what());
    }
  }
  return plan;
}

namespace {

/// run_study_task on points already expanded (a worker runs many tasks).
bool run_task(const Study& s, const std::vector<StudyPoint>& points, char kind, size_t point_index,
              const std::string& dir) {
  if (point_index >= points.size()) throw UserError(fmt::format("{}: no point {}", s.path, point_index));
  const StudyPoint& p = points[point_index];
  try {
    if (kind == 'c')
      capture_input(s, p, dir);
    else if (kind == 'r')
      render_reference(s, p, dir);
    else if (kind == 'p')
      run_point(s, p, dir);
    else
      throw UserError(std::string("study task: unknown kind ") + kind + " (c, r or p)");
    return true;
  } catch (const std::exception& e) {
    fs::path f = point_dir(dir, p) / "error.txt";
    if (kind == 'c' || kind == 'r') {
      const ResolvedPoint r = resolve_point(s, p, dir);  // planned, so it resolves
      const std::string& key = kind == 'c' ? r.capture_key : r.reference_key;
      const std::string name = key.empty() ? p.hash : key;  // a task the point does not need
      f = kind == 'c' ? capture_error_path(dir, name) : ref_error_path(dir, name);
    }
    fs::create_directories(f.parent_path());
    write_text_output(f.string(), std::string(e.what()) + "\n");
    return false;
  }
}

}  // namespace

bool run_study_task(const Study& s, char kind, size_t point_index, const std::string& dir) {
  return run_task(s, expand_study(s), kind, point_index, dir);
}

namespace {

/// A worker process: reads tasks ("c N", "r N" or "p N") from in_fd, answers
/// "N ok" or "N fail" on out_fd; the error goes to the task's error file.
[[noreturn]] void worker_main(const Study& s, const std::vector<StudyPoint>& points, const std::string& dir, int in_fd,
                              int out_fd) {
  FILE* in = fdopen(in_fd, "r");
  char kind = 0;
  size_t index = 0;
  while (in && std::fscanf(in, " %c %zu", &kind, &index) == 2) {
    bool ok = false;
    try {
      ok = run_task(s, points, kind, index, dir);
    } catch (...) {
    }
    const std::string reply = fmt::format("{} {} {}\n", kind, index, ok ? "ok" : "fail");
    if (::write(out_fd, reply.data(), reply.size()) != ssize_t(reply.size())) break;
  }
  std::fflush(nullptr);
  _exit(0);
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
  std::set<std::string> failed_refs, failed_caps;

  const size_t n_workers = std::max<size_t>(1, std::min<size_t>(o.jobs, caps.size() + refs.size() + runs.size()));
  std::vector<Worker> workers(n_workers);
  std::fflush(nullptr);
  for (auto& w : workers) {
    int down[2], up[2];
    if (pipe(down) != 0 || pipe(up) != 0) throw UserError("study: cannot create a pipe");
    w.pid = fork();
    if (w.pid < 0) throw UserError("study: cannot start a worker process");
    if (w.pid == 0) {
      close_inherited_folder_locks();
      // The cores are the workers' to share: each point's golden model gets its share.
      set_host_threads(std::max(1, host_threads() / int(n_workers)));
      ::close(down[1]);
      ::close(up[0]);
      for (const auto& other : workers)
        if (other.pid > 0) {
          ::close(other.to);
          ::close(other.from);
        }
      worker_main(s, points, o.out_dir, down[0], up[1]);
    }
    ::close(down[0]);
    ::close(up[1]);
    w.to = down[1];
    w.from = up[0];
  }
  signal(SIGPIPE, SIG_IGN);

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
    for (const auto& w : workers)
      if (w.busy && w.busy->kind == kind) return true;
    return false;
  };
  // Why task t cannot run: its capture (or, for a point, its reference) failed.
  auto broken = [&](const Task& t) -> std::string {
    auto c = capkey_of.find(t.index);
    if (c != capkey_of.end() && failed_caps.count(c->second))
      return "its capture failed: " + recorded_error(capture_error_path(o.out_dir, c->second));
    auto k = key_of.find(t.index);
    if (t.kind == 'p' && k != key_of.end() && failed_refs.count(k->second))
      return "its reference failed: " + recorded_error(ref_error_path(o.out_dir, k->second));
    return "";
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
      if (!broken(t).empty()) {
        failed_refs.insert(key_of[t.index]);
        continue;
      }
      return t;
    }
    if (busy_with('r')) return std::nullopt;
    while (!runs.empty()) {
      Task t = runs.front();
      runs.pop_front();
      if (std::string e = broken(t); !e.empty()) {
        while (!e.empty() && e.back() == '\n') e.pop_back();
        const StudyPoint& p = points[t.index];
        fs::create_directories(point_dir(o.out_dir, p));
        write_text_output((point_dir(o.out_dir, p) / "error.txt").string(), e + "\n");
        db.put_row(row_of(p, "failed", e, nullptr));
        ++sum.failed;
        ++done_now;
        sum.failures.emplace_back(describe_point(p), e);
        continue;
      }
      return t;
    }
    return std::nullopt;
  };
  auto dispatch = [&]() {
    for (auto& w : workers)
      if (w.pid > 0 && !w.busy)
        if (auto t = next_task()) {
          const std::string line = fmt::format("{} {}\n", t->kind, t->index);
          if (::write(w.to, line.data(), line.size()) == ssize_t(line.size())) w.busy = t;
        }
  };
  auto finish = [&](const Task& t, bool ok) {
    const StudyPoint& p = points[t.index];
    if (t.kind == 'c') {
      if (!ok) failed_caps.insert(capkey_of[t.index]);
      return;
    }
    if (t.kind == 'r') {
      if (!ok) failed_refs.insert(key_of[t.index]);
      return;
    }
    ++done_now;
    if (ok && record_from_folder(db, o.out_dir, p) && fs::exists(point_dir(o.out_dir, p) / "report.json")) {
      ++sum.ran;
    } else {
      std::string e = fs::exists(point_dir(o.out_dir, p) / "error.txt")
                          ? read_file(point_dir(o.out_dir, p) / "error.txt")
                          : std::string("the worker running it stopped");
      while (!e.empty() && e.back() == '\n') e.pop_back();
      db.put_row(row_of(p, "failed", e, nullptr));
      ++sum.failed;
      sum.failures.emplace_back(describe_point(p), e);
    }
    progress(false);
  };

  dispatch();
  for (;;) {
    std::vector<pollfd> fds;
    std::vector<Worker*> who;
    for (auto& w : workers)
      if (w.pid > 0 && w.busy) {
        fds.push_back(pollfd{w.from, POLLIN, 0});
        who.push_back(&w);
      }
    if (fds.empty()) break;
    if (poll(fds.data(), fds.size(), -1) < 0) {
      if (errno == EINTR) continue;
      throw UserError("study: poll failed");
    }
    for (size_t i = 0; i < fds.size(); ++i) {
      if (!(fds[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
      Worker& w = *who[i];
      char buf[256];
      const ssize_t n = ::read(w.from, buf, sizeof buf);
      if (n <= 0) {  // the worker died: its task fails, the others go on
        const Task t = *w.busy;
        w.busy.reset();
        ::close(w.to);
        ::close(w.from);
        int st = 0;
        waitpid(w.pid, &st, 0);
        w.pid = -1;
        finish(t, false);
        continue;
      }
      w.buf.append(buf, size_t(n));
      size_t nl;
      while ((nl = w.buf.find('\n')) != std::string::npos) {
        const std::string line = w.buf.substr(0, nl);
        w.buf.erase(0, nl + 1);
        if (w.busy) {
          const Task t = *w.busy;
          w.busy.reset();
          finish(t, line.size() >= 2 && line.compare(line.size() - 2, 2, "ok") == 0);
        }
      }
    }
    dispatch();
  }
  for (auto& w : workers)
    if (w.pid > 0) {
      ::close(w.to);
      ::close(w.from);
      int st = 0;
      waitpid(w.pid, &st, 0);
    }
  // Points a dead worker left (no worker remained to run them).
  while (!runs.empty()) {
    const StudyPoint& p = points[runs.front().index];
    runs.pop_front();
    db.put_row(row_of(p, "failed", "no worker process was left to run it", nullptr));
    ++sum.failed;
    sum.failures.emplace_back(describe_point(p), "no worker process was left to run it");
  }
  progress(true);
  return sum;
}

std::string study_file_of(const std::string& dir) {
  const fs::path db_path = fs::path(dir) / "results.db";
  if (!fs::exists(db_path)) throw UserError(dir + ": not a study folder (no results.db)");
  Db db(db_path.string());
  sqlite3_stmt* st = db.prepare("SELECT value FROM study WHERE key = 'file'");
  std::string file;
  if (sqlite3_step(st) == SQLITE_ROW) file = reinterpret_cast<const char*>(sqlite3_column_text(st, 0));
  sqlite3_finalize(st);
  if (file.empty()) throw UserError(dir + ": the database does not name its study file");
  return file;
}

void export_study_csv(const std::string& dir, const std::string& csv_path) {
  const fs::path db_path = fs::path(dir) / "results.db";
  if (!fs::exists(db_path)) throw UserError(dir + ": not a study folder (no results.db)");
  Db db(db_path.string());
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
  while (sqlite3_step(st) == SQLITE_ROW) {
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
}

}  // namespace ropsim
