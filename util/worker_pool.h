// A pool of forked worker processes, the one the study runner and the
// sampled fidelity share: SystemC allows one simulation context per thread
// of control, so parallel simulations are processes.
//
//  - Each worker is forked from the caller, runs at_start() once (close what
//    it must not hold, take its share of the host threads), then serves the
//    tasks the parent sends it, one at a time: serve(task) in the worker, its
//    reply back to the parent. Tasks and replies are byte strings, framed by
//    their length.
//  - A task whose serve throws is a failed reply, classified by the one rule
//    of errors.h (status 1: a user or environment error, 2: a broken
//    invariant) with the error's text; the worker goes on.
//  - A worker that dies (a signal, an exit) fails the task it held with
//    kDied and is gone; the others go on.
//  - close() ends every worker once its task is done, reaps it, and sums the
//    CPU seconds the workers used; the destructor does the same, but first
//    kills the workers still holding a task (the caller left early).
// Bottom layer: POSIX and the standard library only.
#pragma once
#include <sys/types.h>

#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace ropsim {

class WorkerPool {
 public:
  using Serve = std::function<std::string(const std::string& task)>;

  /// Forks n >= 1 workers (UserError when the system refuses a pipe or a fork).
  WorkerPool(size_t n, Serve serve, std::function<void()> at_start = {});
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  size_t size() const { return workers_.size(); }
  /// Worker w is alive and holds no task.
  bool idle(size_t w) const { return workers_[w].pid > 0 && !workers_[w].busy; }
  /// Some worker is alive.
  bool any_alive() const;
  /// Some worker holds a task.
  bool any_busy() const;
  /// Sends a task to idle worker w.
  void send(size_t w, const std::string& task);

  struct Reply {
    enum class Kind { kOk, kFailed, kDied };
    size_t worker = 0;
    Kind kind = Kind::kOk;
    int status = 0;    ///< kFailed: the error's exit status (errors.h: 1 or 2)
    std::string text;  ///< kOk: serve's reply; otherwise the error, on one line
    bool ok() const { return kind == Kind::kOk; }
  };
  /// Waits for the next reply of a busy worker (none busy: an InternalError).
  Reply next();

  /// Ends every worker and reaps it; returns the CPU seconds (user and
  /// system) the workers used. Idempotent.
  double close();

 private:
  struct Worker {
    pid_t pid = -1;
    int to = -1, from = -1;
    bool busy = false;
    std::string in;  // bytes read, not yet a whole message
  };
  void reap(Worker& w, int* status);
  std::vector<Worker> workers_;
  double cpu_seconds_ = 0;
};

}  // namespace ropsim
