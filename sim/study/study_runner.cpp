#include "sim/study/study_runner.h"

#include <fmt/format.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <map>
#include <optional>
#include <system_error>

#include "sim/study/study_db.h"
#include "sim/study/study_folder.h"
#include "util/errors.h"
#include "util/host_threads.h"
#include "util/output_file.h"
#include "util/progress.h"
#include "util/version.h"
#include "util/worker_pool.h"

namespace fs = std::filesystem;

namespace ropsim {

int study_exit_status(const StudySummary& sum, size_t not_run) {
  int st = sum.failed || not_run ? kUserErrorStatus : 0;
  for (const auto& f : sum.failures) st = std::max(st, f.status);
  return st;
}

std::string count_of(size_t n, const char* noun) { return fmt::format("{} {}{}", n, noun, n == 1 ? "" : "s"); }

std::string describe_point(const StudyPoint& p) {
  std::string s = p.hash + " (" + p.input;
  for (const auto& [k, v] : p.params) s += ", " + k + "=" + to_string(v);
  return s + ")";
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

/// A task of the work graph, as the scheduler holds it.
struct Task {
  char kind;     ///< 'c': capture a mesh input, 'r': render a reference, 'p': run a point
  size_t index;  ///< the point (for 'c' and 'r': a point that names the capture or reference)
};

/// Checks that the study folder dir holds s (o.use), naming the folder and
/// the study recorded there when it does not. Returns true when its results
/// must be removed first (--force, whatever study they are of).
///
/// Two studies are the same when they have the same points, a point being
/// its hash: every parameter, the contents of the design files it names, the
/// reference settings and ropsim's version. The study's name, its file's
/// place and text beyond the points (comments, [slurm]) may change.
bool replaces_folder(StudyDb& db, const Study& s, const std::vector<StudyPoint>& points, const StudyRunOptions& o) {
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
      StudyDb db(db_path);
      replace = replaces_folder(db, s, points, o);
    }
    if (replace) remove_study_results(o.out_dir);
  }
  fs::create_directories(fs::path(o.out_dir) / "points", ec);
  if (!ec) fs::create_directories(fs::path(o.out_dir) / "refs", ec);
  if (!ec) fs::create_directories(fs::path(o.out_dir) / "traces", ec);
  if (ec) throw UserError(o.out_dir + ": cannot create the study folder: " + ec.message());
  write_text_output((fs::path(o.out_dir) / "study.toml").string(), read_whole_file(s.path));
  std::map<std::string, size_t> ref_of, capture_of;  // key -> the first point naming it
  StudyDb db(db_path);
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
    const FolderOutcome in_folder = record_from_folder(db, o.out_dir, p);
    if (in_folder == FolderOutcome::kOk) {
      ++sum.reused;
      continue;
    }
    StudyFailure kind = in_folder == FolderOutcome::kHostFailure ? StudyFailure::kHost : StudyFailure::kInput;
    std::string error =
        in_folder == FolderOutcome::kNone
            ? ""
            : recorded_error(point_dir(o.out_dir, p) / (kind == StudyFailure::kHost ? "host-error.txt" : "error.txt"));
    if (in_folder == FolderOutcome::kNone && it != status.end()) {  // the row's failure, its folder gone or cleared
      kind = it->second.failure;
      error = it->second.error;
    }
    const bool failed = in_folder != FolderOutcome::kNone || it != status.end();
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
      n_workers, [&](const std::string& task) { return serve_study_task(s, points, o.out_dir, task); },
      [n_workers] {
        close_inherited_folder_locks();
        // The cores are the workers' to share: each point's golden model gets its share.
        set_host_threads(std::max(1, host_threads() / int(n_workers)));
      });
  std::vector<std::optional<Task>> held(n_workers);  // each worker's task

  StudyDb db((fs::path(o.out_dir) / "results.db").string());
  size_t done_now = 0, total_now = runs.size();
  Progress line(
      [&](double el) {
        const size_t rem = total_now - done_now, done = sum.reused + sum.ran + sum.failed;
        const std::string eta =
            done_now && rem ? ", ETA " + Progress::format_duration(el / double(done_now) * double(rem)) : "";
        return fmt::format("study {}: {} of {} points done ({:.1f} %), {} failed, {} remaining, {}{}", s.name, done,
                           sum.points, sum.points ? 100.0 * double(done) / double(sum.points) : 100.0, sum.failed, rem,
                           Progress::format_duration(el), eta);
      },
      o.progress);
  auto progress = [&](bool final) {
    if (final)
      line.finish();
    else
      line.tick();
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
    if (res.ok && record_from_folder(db, o.out_dir, p) == FolderOutcome::kOk) {
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
      finish(t, parse_task_reply(r.text));
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

}  // namespace ropsim
