// `ropsim study`: run a what-if study (docs/studies.md) on this machine, list
// its points, export its results, or write its HTML report (which is drawn by
// analysis/study_report.py on Debian's /usr/bin/python3).
#include <fmt/format.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <thread>
#include <vector>

#include "sim/cli/cli_common.h"
#include "sim/study/slurm_executor.h"
#include "sim/study/study.h"
#include "sim/study/study_runner.h"

namespace ropsim {

namespace {

struct StudyOpts {
  std::string file, out, dir, csv, kind;
  std::string mesh_dir;  ///< --mesh-dir: searched first for a mesh scene's meshes
  unsigned jobs = 0;
  size_t index = 0;
  bool retry_failed = false, quiet = false;
  bool force = false, extend = false;  ///< study run: the folder holds another study's results
  bool recorded_ok = false;            ///< study task: a failure whose error is recorded exits 0
  std::string executor = "local";
  bool wait = false;
  StudySlurm slurm;  ///< --slurm-* (empty: the study file's)
  std::vector<std::string> slurm_args;
};

std::string out_dir(const StudyOpts& o, const Study& s) { return o.out.empty() ? "out/study/" + s.name : o.out; }

/// `study plan`: records what the folder holds, prints what is left as JSON.
int cmd_study_plan(const StudyOpts& o) {
  const Study s = load_study(o.file, o.mesh_dir);
  check_study_inputs(s);
  StudyRunOptions ro;
  ro.out_dir = out_dir(o, s);
  ro.retry_failed = o.retry_failed;
  StudySummary sum;
  const StudyPlan plan = plan_study(s, ro, sum);
  nlohmann::ordered_json j;
  j["study"] = s.name;
  j["folder"] = ro.out_dir;
  j["points"] = sum.points;
  j["done"] = sum.reused;
  j["failed"] = sum.failed;
  j["captures"] = plan.captures;
  j["references"] = plan.references;
  j["runs"] = plan.points;
  fmt::print("{}\n", j.dump());
  return 0;
}

/// `study task`: one capture, reference or point, in this process.
int cmd_study_task(const StudyOpts& o) {
  const Study s = load_study(o.file, o.mesh_dir);
  const std::string dir = out_dir(o, s);
  const StudyTaskResult res = run_study_task(s, o.kind[0], o.index, dir);
  if (res.ok) return 0;
  // A host failure is not the task's verdict: the task fails, so that the
  // phases after it do not run on a missing capture or reference.
  if (o.recorded_ok && o.kind != "p" && res.recorded && res.failure == StudyFailure::kInput) {
    std::fprintf(stderr, "ropsim: study task %s %zu failed; its error is recorded for the points that need it\n",
                 o.kind.c_str(), o.index);
    return 0;
  }
  const int status = failure_status(res.error);
  if (status == kInternalErrorStatus) {  // "ropsim: internal error: ...", as main says it
    std::fprintf(stderr, "ropsim: internal error: study task %s %zu failed: %s: please report it\n", o.kind.c_str(),
                 o.index, broken_invariant(res.error).c_str());
    return status;
  }
  std::fprintf(stderr, "ropsim: error: study task %s %zu failed (%s): %s\n", o.kind.c_str(), o.index,
               res.failure == StudyFailure::kHost ? "its host failed" : "an input error", res.error.c_str());
  return status;
}

/// One line per failed point, its kind of failure named.
void print_failures(const StudySummary& sum) {
  for (const auto& f : sum.failures)
    fmt::print("  failed{}: {}: {}\n", f.kind == StudyFailure::kHost ? " (host)" : "", f.point, f.error);
}

/// Point index -> its task's log and the logs of the phase before it.
using TaskLogs = std::map<size_t, std::pair<std::string, std::string>>;
int collect_summary(const Study& s, const std::string& dir, const TaskLogs& logs = {});

/// `study collect`: records every finished task's result in the database.
int cmd_study_collect(const StudyOpts& o) { return collect_summary(load_study(study_file_of(o.dir)), o.dir); }

/// Prints the summary of a study folder after its tasks ran elsewhere; 1 when
/// a point failed or did not run. logs: the task log of a point submitted
/// (by index), named for the points that did not run.
int collect_summary(const Study& s, const std::string& dir, const TaskLogs& logs) {
  StudyRunOptions ro;
  ro.out_dir = dir;
  StudySummary sum;
  const StudyPlan plan = plan_study(s, ro, sum);
  fmt::print("study {}: {} points: {} done, {} failed, {} not run yet; results in {}/results.db\n", s.name, sum.points,
             sum.reused, sum.failed, plan.points.size(), dir);
  print_failures(sum);
  const std::vector<StudyPoint> points = logs.empty() ? std::vector<StudyPoint>{} : expand_study(s);
  for (size_t pi : plan.points)
    if (auto it = logs.find(pi); it != logs.end()) {
      std::error_code ec;
      if (std::filesystem::exists(it->second.first, ec))
        fmt::print("  not run: {}: its task ended without a result (killed? out of time or memory?); log: {}\n",
                   describe_point(points.at(pi)), it->second.first);
      else
        fmt::print("  not run: {}: its task never started; the phase before it failed: {}\n",
                   describe_point(points.at(pi)), it->second.second);
    }
  return study_exit_status(sum, plan.points.size());
}

/// `study run --executor slurm`: submits what the folder lacks as job arrays.
int cmd_study_run_slurm(const StudyOpts& o, const Study& s, const StudyRunOptions& ro) {
  SlurmOptions so;
  so.sbatch = s.slurm;
  if (!o.slurm.partition.empty()) so.sbatch.partition = o.slurm.partition;
  if (!o.slurm.time.empty()) so.sbatch.time = o.slurm.time;
  if (!o.slurm.mem.empty()) so.sbatch.mem = o.slurm.mem;
  if (o.slurm.throttle) so.sbatch.throttle = o.slurm.throttle;
  for (const auto& a : o.slurm_args) so.sbatch.args.push_back(a);
  so.wait = o.wait;
  StudySummary sum;
  const SlurmSubmission sub = submit_study_slurm(s, ro, so, sum);
  fmt::print("study {}: {} points: {} already done, {} failed; submitted {} captures, {} references, {} points\n",
             s.name, sum.points, sum.reused, sum.failed, sub.plan.captures.size(), sub.plan.references.size(),
             sub.plan.points.size());
  TaskLogs logs;
  const std::filesystem::path sdir = (std::filesystem::absolute(ro.out_dir) / "slurm").lexically_normal();
  for (size_t i = 0; i < sub.job_ids.size(); ++i) {
    fmt::print("  job {}: {}{}\n", sub.job_ids[i],
               sub.kinds[i] == 'c'   ? "captures"
               : sub.kinds[i] == 'r' ? "references"
                                     : "points",
               sub.after[i].empty() ? "" : " (afterok " + sub.after[i] + ")");
    if (sub.kinds[i] == 'p')
      for (size_t t = 0; t < sub.plan.points.size(); ++t)
        logs[sub.plan.points[t]] = {(sdir / fmt::format("{}_{}.log", sub.job_ids[i], t)).string(),
                                    (sdir / fmt::format("{}_*.log", sub.after[i])).string()};
  }
  std::fflush(stdout);
  if (!o.wait) return study_exit_status(sum);
  wait_slurm_jobs(sub.job_ids, so.poll_ms);
  return collect_summary(s, ro.out_dir, logs);
}

int cmd_study_run(const StudyOpts& o) {
  const Study s = load_study(o.file, o.mesh_dir);  // a bad file is refused before anything runs
  check_study_inputs(s);                           // and so is a missing mesh, texture or material library
  StudyRunOptions ro;
  ro.out_dir = out_dir(o, s);
  ro.use = o.force ? StudyFolderUse::kReplace : o.extend ? StudyFolderUse::kExtend : StudyFolderUse::kSameStudy;
  if (o.executor == "slurm") {
    ro.retry_failed = o.retry_failed;
    return cmd_study_run_slurm(o, s, ro);
  }
  ro.jobs = o.jobs ? o.jobs : std::max(1u, std::thread::hardware_concurrency());
  ro.retry_failed = o.retry_failed;
  ro.progress = !o.quiet;
  const StudySummary r = run_study(s, ro);
  if (!o.quiet || r.failed) {
    fmt::print("study {}: {}: {} run, {} already done, {}; results in {}/results.db\n", s.name,
               count_of(r.points, "point"), count_of(r.ran, "point"), r.reused, describe_failures(r), ro.out_dir);
    print_failures(r);
  }
  return study_exit_status(r);
}

int cmd_study_points(const StudyOpts& o) {
  const Study s = load_study(o.file);
  for (const auto& p : expand_study(s)) fmt::print("{} {}\n", p.hash, p.params_json().dump());
  return 0;
}

#ifndef ROPSIM_SOURCE_DIR
#define ROPSIM_SOURCE_DIR ""
#endif

constexpr const char* kPython = "/usr/bin/python3";

/// analysis/study_report.py next to the executable (<exe dir>/../analysis:
/// the source tree for build/ropsim), else in the source tree it was built from.
std::string study_report_script() {
  namespace fs = std::filesystem;
  std::vector<fs::path> tried;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) tried.push_back(exe.parent_path().parent_path() / "analysis" / "study_report.py");
  if (*ROPSIM_SOURCE_DIR) tried.push_back(fs::path(ROPSIM_SOURCE_DIR) / "analysis" / "study_report.py");
  for (const auto& p : tried)
    if (fs::is_regular_file(p, ec)) return p.lexically_normal().string();
  std::string where;
  for (const auto& p : tried) where += (where.empty() ? "" : ", ") + p.lexically_normal().string();
  throw UserError("study report: analysis/study_report.py not found (looked for " + where + ")");
}

int cmd_study_report(const StudyOpts& o) {
  const std::string script = study_report_script();
  if (::access(kPython, X_OK) != 0)
    throw UserError(std::string("study report: ") + kPython + ": " + std::strerror(errno) +
                    " (install python3-pandas and python3-matplotlib: scripts/deps.sh)");
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = ::fork();
  if (pid < 0) throw UserError(std::string("study report: fork: ") + std::strerror(errno));
  if (pid == 0) {
    ::signal(SIGPIPE, SIG_DFL);  // ropsim ignores it (output_file.h); the script gets the default
    if (o.out.empty())
      ::execl(kPython, kPython, script.c_str(), o.dir.c_str(), static_cast<char*>(nullptr));
    else
      ::execl(kPython, kPython, script.c_str(), o.dir.c_str(), "--out", o.out.c_str(), static_cast<char*>(nullptr));
    std::fprintf(stderr, "ropsim: error: study report: %s: %s\n", kPython, std::strerror(errno));
    ::_exit(1);
  }
  int st = 0;
  while (::waitpid(pid, &st, 0) < 0)
    if (errno != EINTR) throw UserError(std::string("study report: waitpid: ") + std::strerror(errno));
  if (WIFEXITED(st)) return WEXITSTATUS(st);
  throw UserError(fmt::format("study report: {} was killed by signal {}", script, WTERMSIG(st)));
}

}  // namespace

VerbRunner add_study_command(CLI::App& app) {
  auto o = std::make_shared<StudyOpts>();
  CLI::App* st = app.add_subcommand("study", "What-if studies: sweep parameters, collect results (docs/studies.md)");
  st->require_subcommand(1);
  st->footer(examples({"ropsim study points studies/smoke.toml", "ropsim study run studies/smoke.toml -o st -j 2",
                       "ropsim study export st -o st.csv"}));
  CLI::App* run = st->add_subcommand("run", "Run the points of a study that its folder does not hold yet");
  run->add_option("STUDY", o->file, "Study file (TOML)")->required();
  run->add_option("-o,--out", o->out, "Study folder (default out/study/NAME)")->type_name("DIR");
  run->add_option("-j,--jobs", o->jobs, "Worker processes (default: the cores)")->check(in_range(1u, 1024u));
  run->add_flag("--retry-failed", o->retry_failed,
                "Run again the points whose input error is recorded (host failures always run again)");
  CLI::Option* force = run->add_flag("--force", o->force,
                                     "Replace the folder's results (another study's, or this one's) before running");
  run->add_flag("--extend", o->extend,
                "The study adds points to those the folder holds: keep them, run the new ones (refused if one of "
                "them changed)")
      ->excludes(force);
  run->add_flag("--quiet", o->quiet, "No progress line; print only failures");
  const char* mesh_dir_help =
      "Folder to look for the mesh scenes' meshes in first (default: $ROPSIM_MESH_DIR), then each scene's mesh_dir";
  run->add_option("--mesh-dir", o->mesh_dir, mesh_dir_help);
  run->add_option("--executor", o->executor, "local (worker processes here) or slurm (job arrays, sbatch)")
      ->check(CLI::IsMember({"local", "slurm"}));
  run->add_flag("--wait", o->wait, "slurm: wait for the jobs to end, then record their results (study collect)");
  run->add_option("--slurm-partition", o->slurm.partition, "slurm: sbatch --partition (over [slurm] partition)");
  run->add_option("--slurm-time", o->slurm.time, "slurm: sbatch --time per task (over [slurm] time)");
  run->add_option("--slurm-mem", o->slurm.mem, "slurm: sbatch --mem per task (over [slurm] mem)");
  run->add_option("--slurm-throttle", o->slurm.throttle, "slurm: array tasks at once (over [slurm] throttle)")
      ->check(in_range(1u, 100000u));
  run->add_option("--slurm-arg", o->slurm_args, "slurm: an extra sbatch argument (repeatable; after [slurm] args)");
  run->footer(
      examples({"ropsim study run studies/smoke.toml -o st -j 2",
                "ropsim study run studies/smoke.toml -o st --retry-failed --quiet   # resumes: runs what st lacks"}));
  CLI::App* pts = st->add_subcommand("points", "List the points of a study (hash and parameters) without running");
  pts->add_option("STUDY", o->file, "Study file (TOML)")->required();
  pts->footer(examples({"ropsim study points studies/smoke.toml", "ropsim study points studies/designs.toml"}));
  CLI::App* exp = st->add_subcommand("export", "Write a study folder's results as CSV");
  exp->add_option("DIR", o->dir, "Study folder")->required();
  exp->add_option("-o,--out,--csv", o->csv, "CSV file to write (- for standard output)")->required()->type_name("FILE");
  exp->footer(examples({"ropsim study export st -o st.csv", "ropsim study export st -o -   # to standard output"}));
  CLI::App* plan = st->add_subcommand("plan", "Record what a study folder holds; print the tasks left as JSON");
  plan->add_option("STUDY", o->file, "Study file (TOML)")->required();
  plan->add_option("-o,--out", o->out, "Study folder (default out/study/NAME)")->type_name("DIR");
  plan->add_flag("--retry-failed", o->retry_failed, "Plan the points whose error is recorded again");
  plan->add_option("--mesh-dir", o->mesh_dir, mesh_dir_help);
  plan->footer(examples(
      {"ropsim study plan studies/smoke.toml -o st", "ropsim study plan studies/smoke.toml -o st --retry-failed"}));
  CLI::App* task = st->add_subcommand("task", "Run one task of a study in this process (for other executors)");
  task->add_option("STUDY", o->file, "Study file (TOML)")->required();
  task->add_option("-o,--out", o->out, "Study folder (default out/study/NAME)")->type_name("DIR");
  task->add_option("--kind", o->kind, "c (capture), r (reference) or p (point)")
      ->required()
      ->check(CLI::IsMember({"c", "r", "p"}));
  task->add_option("--index", o->index, "The point (for c and r: the point that names the capture or reference)")
      ->required();
  task->add_option("--mesh-dir", o->mesh_dir, mesh_dir_help);
  task->add_flag("--recorded-ok", o->recorded_ok,
                 "Exit 0 when the task failed but recorded its error (a capture's or reference's: the points "
                 "that need it record it as theirs)");
  task->footer(examples({"ropsim study task studies/smoke.toml -o st --kind p --index 0",
                         "ropsim study task studies/smoke.toml -o st --kind p --index 1 --recorded-ok"}));
  CLI::App* col = st->add_subcommand("collect", "Record every finished task of a study folder in its database");
  col->add_option("DIR", o->dir, "Study folder")->required();
  col->footer(examples({"ropsim study collect st", "ropsim study export st -o st.csv   # then its results as CSV"}));
  CLI::App* rep = st->add_subcommand("report", "Write a study folder's HTML report and Markdown summary (DIR/report)");
  rep->add_option("DIR", o->dir, "Study folder")->required();
  rep->add_option("-o,--out", o->out, "Folder for index.html and summary.md (default DIR/report; DIR is only read)");
  rep->footer(examples({"ropsim study run studies/smoke.toml -o st -j 2   # first the study's results",
                        "ropsim study report st   # then st/report/index.html and st/report/summary.md"}));
  return [o, st, run, pts, exp, rep, plan, task, col]() {
    if (!st->parsed()) return -1;
    if (run->parsed()) return cmd_study_run(*o);
    if (pts->parsed()) return cmd_study_points(*o);
    if (exp->parsed()) {
      OutputPlan plan;
      plan.input("DIR's results.db", (std::filesystem::path(o->dir) / "results.db").string());
      plan.input("DIR's study.toml", (std::filesystem::path(o->dir) / "study.toml").string());
      plan.output("--csv", o->csv);
      plan.check();
      const StudyExport ex = export_study_csv(o->dir, o->csv);
      // What it wrote, on standard error when the table went to standard output.
      const std::string said =
          fmt::format("study {}: {} ({} ok, {} failed), {} written to {}\n", ex.study.empty() ? o->dir : ex.study,
                      count_of(ex.rows, "point"), ex.ok, ex.failed, count_of(ex.columns, "column"),
                      o->csv == "-" ? "standard output" : o->csv);
      std::fputs(said.c_str(), o->csv == "-" ? stderr : stdout);
      return 0;
    }
    if (rep->parsed()) return cmd_study_report(*o);
    if (plan->parsed()) return cmd_study_plan(*o);
    if (task->parsed()) return cmd_study_task(*o);
    if (col->parsed()) return cmd_study_collect(*o);
    return -1;
  };
}

}  // namespace ropsim
