// The worker pool (util/worker_pool.h) the study runner and the sampled
// fidelity share: replies come back by task and worker, a task that throws
// is a failed reply classified by the one rule of errors.h, a worker that
// dies fails its task alone, and close() reaps every worker.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <map>
#include <set>
#include <string>

#include "util/errors.h"
#include "util/worker_pool.h"

namespace ropsim {
namespace {

using Kind = WorkerPool::Reply::Kind;

// Every task is served once, by some worker, and comes back whole, however
// long (a reply larger than a pipe's buffer included).
TEST(WorkerPool, EveryTaskComesBackOnceWithItsReply) {
  WorkerPool pool(2, [](const std::string& t) { return t == "big" ? std::string(1 << 20, 'x') : "re:" + t; });
  std::map<std::string, std::string> got;
  std::vector<std::string> tasks = {"a", "b", "big", "c", "d", "e"};
  std::map<size_t, std::string> held;  // worker -> task
  size_t next = 0;
  while (got.size() < tasks.size()) {
    for (size_t w = 0; w < pool.size() && next < tasks.size(); ++w)
      if (pool.idle(w)) {
        held[w] = tasks[next];
        pool.send(w, tasks[next++]);
      }
    const WorkerPool::Reply r = pool.next();
    ASSERT_EQ(r.kind, Kind::kOk) << r.text;
    const std::string task = held.at(r.worker);
    EXPECT_TRUE(got.emplace(task, r.text).second) << "task " << task << " came back twice";
  }
  for (const auto& t : tasks)
    EXPECT_EQ(got[t], t == "big" ? std::string(1 << 20, 'x') : "re:" + t) << "the reply to task " << t;
  EXPECT_FALSE(pool.any_busy());
  EXPECT_GE(pool.close(), 0.0);
  EXPECT_FALSE(pool.any_alive()) << "close() left a worker";
}

// A task that throws fails with its error's exit status and text; the worker
// serves the next task.
TEST(WorkerPool, AThrowingTaskFailsWithItsStatusAndTheWorkerGoesOn) {
  WorkerPool pool(1, [](const std::string& t) -> std::string {
    if (t == "user") throw UserError("bad input file x.trace: record 3");
    if (t == "internal") invariant(false, "tokens retired <= tokens issued");
    return "fine";
  });
  pool.send(0, "user");
  WorkerPool::Reply r = pool.next();
  EXPECT_EQ(r.kind, Kind::kFailed);
  EXPECT_EQ(r.status, kUserErrorStatus);
  EXPECT_EQ(r.text, "bad input file x.trace: record 3");
  pool.send(0, "internal");
  r = pool.next();
  EXPECT_EQ(r.kind, Kind::kFailed);
  EXPECT_EQ(r.status, kInternalErrorStatus);
  EXPECT_NE(r.text.find("tokens retired <= tokens issued"), std::string::npos) << r.text;
  pool.send(0, "ok");
  r = pool.next();
  EXPECT_EQ(r.kind, Kind::kOk) << "the worker did not go on after a failed task: " << r.text;
  EXPECT_EQ(r.text, "fine");
}

// A worker that dies fails the task it held and is gone; the others go on.
TEST(WorkerPool, AWorkerThatDiesFailsItsTaskAlone) {
  WorkerPool pool(2, [](const std::string& t) -> std::string {
    if (t == "die") ::raise(SIGKILL);
    return "ok";
  });
  pool.send(0, "die");
  WorkerPool::Reply r = pool.next();
  EXPECT_EQ(r.kind, Kind::kDied);
  EXPECT_EQ(r.worker, 0u);
  EXPECT_NE(r.text.find("killed by signal 9"), std::string::npos) << r.text;
  EXPECT_FALSE(pool.idle(0)) << "a dead worker was offered a task";
  EXPECT_TRUE(pool.any_alive());
  pool.send(1, "x");
  r = pool.next();
  EXPECT_EQ(r.kind, Kind::kOk) << r.text;
  EXPECT_EQ(r.worker, 1u);
}

// at_start runs once in each worker, before its first task, and not in the
// caller.
TEST(WorkerPool, AtStartRunsInEachWorkerNotInTheCaller) {
  static int started = 0;
  started = 0;
  WorkerPool pool(
      2, [](const std::string&) { return std::to_string(started) + " " + std::to_string(::getpid()); },
      [] { ++started; });
  std::set<std::string> pids;
  for (size_t w = 0; w < 2; ++w) {
    pool.send(w, "");
    const WorkerPool::Reply r = pool.next();
    ASSERT_EQ(r.kind, Kind::kOk) << r.text;
    EXPECT_EQ(r.text.substr(0, 2), "1 ") << "at_start did not run exactly once in the worker";
    pids.insert(r.text.substr(2));
  }
  EXPECT_EQ(started, 0) << "at_start ran in the caller";
  EXPECT_EQ(pids.size(), 2u) << "two workers are two processes";
  EXPECT_EQ(pids.count(std::to_string(::getpid())), 0u) << "a task ran in the caller";
}

}  // namespace
}  // namespace ropsim
