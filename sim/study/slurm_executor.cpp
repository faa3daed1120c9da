#include "sim/study/slurm_executor.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include "util/errors.h"

namespace ropsim {

namespace fs = std::filesystem;

namespace {

/// s quoted for the shell.
std::string sh(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

/// Runs a shell command; returns its exit status (-1 when killed) and its
/// standard output and error together. The command starts with SIGPIPE and
/// SIGXFSZ at their defaults (ropsim ignores both, and an ignored signal
/// survives exec), so a pipeline in it ends as it would from a shell.
int run_command(const std::string& cmd, std::string& out) {
  out.clear();
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) throw UserError("study run: cannot run " + cmd + ": " + std::strerror(errno));
  posix_spawn_file_actions_t actions;
  posix_spawnattr_t attr;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);
  posix_spawn_file_actions_adddup2(&actions, fds[1], STDERR_FILENO);
  posix_spawnattr_init(&attr);
  sigset_t defaults;
  sigemptyset(&defaults);
  sigaddset(&defaults, SIGPIPE);
  sigaddset(&defaults, SIGXFSZ);
  posix_spawnattr_setsigdefault(&attr, &defaults);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGDEF);
  const std::string line = cmd;
  char* const argv[] = {const_cast<char*>("sh"), const_cast<char*>("-c"), const_cast<char*>(line.c_str()), nullptr};
  pid_t pid = -1;
  const int err = ::posix_spawn(&pid, "/bin/sh", &actions, &attr, argv, environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  ::close(fds[1]);
  if (err != 0) {
    ::close(fds[0]);
    throw UserError("study run: cannot run " + cmd + ": " + std::strerror(err));
  }
  char buf[4096];
  for (;;) {
    const ssize_t n = ::read(fds[0], buf, sizeof buf);
    if (n > 0) {
      out.append(buf, static_cast<size_t>(n));
    } else if (n == 0 || errno != EINTR) {
      break;
    }
  }
  ::close(fds[0]);
  int st = 0;
  while (::waitpid(pid, &st, 0) < 0)
    if (errno != EINTR) return -1;
  return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

std::string trim(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.erase(0, 1);
  return s;
}

/// A command's output as one line (an error message is one line): its lines
/// joined by "; ".
std::string one_line(const std::string& s) {
  std::string r;
  std::istringstream in(s);
  for (std::string l; std::getline(in, l);)
    if (!trim(l).empty()) r += (r.empty() ? "" : "; ") + trim(l);
  return r;
}

/// The array job ids squeue lists (every user's queued and running jobs);
/// false when squeue failed. stuck: the jobs pending for a reason that only
/// someone's action ends (held after a failed launch or by an
/// administrator, a dependency that can never be satisfied), with it.
bool queued_jobs(std::set<std::string>& ids, std::string& out, std::map<std::string, std::string>* stuck = nullptr) {
  ids.clear();
  if (run_command("squeue -h -o '%F|%T|%r'", out) != 0) return false;
  static const char* const kStuck[] = {"launch failed requeued held", "JobHeldAdmin", "DependencyNeverSatisfied",
                                       "BadConstraints"};
  std::istringstream in(out);
  std::string line;
  while (std::getline(in, line)) {
    line = trim(line);
    if (line.empty()) continue;
    const size_t a = line.find('|'), b = line.find('|', a == std::string::npos ? a : a + 1);
    const std::string id = line.substr(0, a);
    ids.insert(id);
    if (stuck && b != std::string::npos && line.substr(a + 1, b - a - 1) == "PENDING") {
      const std::string reason = line.substr(b + 1);
      for (const char* r : kStuck)
        if (reason == r) (*stuck)[id] = reason;
    }
  }
  return true;
}

const char* phase_name(char kind) { return kind == 'c' ? "captures" : kind == 'r' ? "references" : "points"; }

}  // namespace

void wait_slurm_jobs(const std::vector<std::string>& job_ids, unsigned poll_ms) {
  int failures = 0;
  const int max_failures = std::max(1, int(30000 / std::max(1u, poll_ms)));  // about 30 s of errors
  for (;;) {
    std::set<std::string> q;
    std::map<std::string, std::string> stuck;
    std::string out;
    if (!queued_jobs(q, out, &stuck)) {
      if (++failures >= max_failures) throw UserError("study run: squeue keeps failing: " + one_line(out));
    } else {
      failures = 0;
      bool any = false;
      for (const auto& id : job_ids) {
        any = any || q.count(id);
        // Waiting would never end.
        if (auto it = stuck.find(id); it != stuck.end())
          throw UserError(fmt::format(
              "study run: SLURM job {} will not run (pending: {}); see the cluster's logs, then scancel {} and "
              "submit again (the tasks that ran are recorded by `ropsim study collect`)",
              id, it->second, id));
      }
      if (!any) return;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(poll_ms));
  }
}

SlurmSubmission submit_study_slurm(const Study& s, const StudyRunOptions& o, const SlurmOptions& so,
                                   StudySummary& sum) {
  const fs::path dir = fs::absolute(o.out_dir).lexically_normal();
  const fs::path sdir = dir / "slurm";
  // Jobs of an earlier submission still queued would run the same tasks again.
  {
    std::ifstream prev(sdir / "jobs.txt");
    std::vector<std::string> ids;
    for (std::string id; prev >> id;) ids.push_back(id);
    std::set<std::string> q;
    std::string out;
    if (!ids.empty() && queued_jobs(q, out)) {
      std::string busy;
      for (const auto& id : ids)
        if (q.count(id)) busy += (busy.empty() ? "" : " ") + id;
      if (!busy.empty())
        throw UserError(
            fmt::format("study run: {}: SLURM jobs {} of an earlier submission are still queued or "
                        "running (wait for them, or scancel them)",
                        dir.string(), busy));
    }
  }
  SlurmSubmission sub;
  sub.plan = plan_study(s, o, sum);
  std::error_code ec;
  fs::create_directories(sdir, ec);
  if (ec) throw UserError("study run: " + sdir.string() + ": " + ec.message());
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (ec) throw UserError("study run: /proc/self/exe: " + ec.message());
  const std::string study_file = fs::absolute(s.path).lexically_normal().string();
  const StudySlurm& b = so.sbatch;

  std::string after;  // the job the next phase depends on
  const std::pair<char, const std::vector<size_t>*> phases[] = {
      {'c', &sub.plan.captures}, {'r', &sub.plan.references}, {'p', &sub.plan.points}};
  for (const auto& [kind, list] : phases) {
    if (list->empty()) continue;
    const std::string name = phase_name(kind);
    const fs::path txt = sdir / (name + ".txt"), script = sdir / (name + ".sbatch");
    {
      std::ofstream f(txt);
      for (size_t i : *list) f << i << "\n";
      if (!f) throw UserError("study run: cannot write " + txt.string());
    }
    {
      std::ofstream f(script);
      f << "#!/bin/bash\n";
      f << "# Written by `ropsim study run --executor slurm`: the " << name << " of study " << s.name << ",\n";
      f << "# one array task per line of " << txt.filename().string() << ".\n";
      f << "#SBATCH --job-name="
        << "ropsim-" << kind << "-" << s.name << "\n";
      f << "#SBATCH --output=" << (sdir / "%A_%a.log").string() << "\n";
      f << "#SBATCH --array=0-" << list->size() - 1;
      if (b.throttle) f << "%" << b.throttle;
      f << "\n";
      f << "#SBATCH --ntasks=1\n";
      if (!b.partition.empty()) f << "#SBATCH --partition=" << b.partition << "\n";
      if (!b.time.empty()) f << "#SBATCH --time=" << b.time << "\n";
      if (!b.mem.empty()) f << "#SBATCH --mem=" << b.mem << "\n";
      f << "set -eu\n";
      f << "index=$(sed -n \"$((SLURM_ARRAY_TASK_ID + 1))p\" " << sh(txt.string()) << ")\n";
      // A capture or reference that fails records its error and exits 0, so
      // that the next phase runs and its points record that error as theirs
      // (afterok would cancel every point of the study). A task that could
      // not record (killed, out of time or memory) still fails the phase.
      f << "exec " << sh(exe.string()) << " study task " << sh(study_file) << " --out " << sh(dir.string())
        << " --kind " << kind << " --index \"$index\"" << (kind == 'p' ? "" : " --recorded-ok")
        << (s.mesh_dir.empty() ? "" : " --mesh-dir " + sh(s.mesh_dir)) << "\n";
      if (!f) throw UserError("study run: cannot write " + script.string());
    }
    std::string cmd = "sbatch --parsable";
    if (!after.empty()) cmd += " --dependency=afterok:" + after + " --kill-on-invalid-dep=yes";
    for (const auto& a : b.args) cmd += " " + sh(a);
    cmd += " " + sh(script.string());
    std::string out;
    const int st = run_command(cmd, out);
    // --parsable prints "jobid" or "jobid;cluster" (after any warnings).
    std::string id = trim(out);
    if (const auto nl = id.rfind('\n'); nl != std::string::npos) id = id.substr(nl + 1);
    id = id.substr(0, id.find(';'));
    if (st != 0 || id.empty() || id.find_first_not_of("0123456789") != std::string::npos) {
      std::string why = st != 0 ? fmt::format("sbatch of the {} failed (exit status {}): {}", name, st, one_line(out))
                                : "sbatch of the " + name + " printed no job id: " + one_line(out);
      if (!b.mem.empty() && out.find("Memory specification can not be satisfied") != std::string::npos)
        why += fmt::format(" (--mem={} per task: more than any node of the partition has)", b.mem);
      // The phases already submitted would run without the rest: cancel them.
      if (!sub.job_ids.empty()) {
        std::string ids, scancel_out;
        for (const auto& j : sub.job_ids) ids += (ids.empty() ? "" : " ") + j;
        const int cst = run_command("scancel " + ids, scancel_out);
        why += cst == 0 ? "; cancelled the jobs already submitted (" + ids + ")"
                        : "; could not cancel the jobs already submitted (" + ids + "): " + one_line(scancel_out);
      }
      throw UserError("study run: " + why);
    }
    sub.job_ids.push_back(id);
    sub.kinds.push_back(kind);
    sub.after.push_back(after);
    after = id;
  }
  std::ofstream jobs(sdir / "jobs.txt");
  for (const auto& id : sub.job_ids) jobs << id << "\n";
  return sub;
}

}  // namespace ropsim
