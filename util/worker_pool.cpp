#include "util/worker_pool.h"

#include <poll.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstring>

#include "util/byte_codec.h"
#include "util/errors.h"

namespace ropsim {

namespace {

bool write_all(int fd, const void* data, size_t n) {
  const char* p = static_cast<const char*>(data);
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return false;
    p += w;
    n -= size_t(w);
  }
  return true;
}

/// Reads exactly n bytes; false at the end of the stream or on an error.
bool read_all(int fd, void* data, size_t n) {
  char* p = static_cast<char*>(data);
  while (n > 0) {
    const ssize_t r = ::read(fd, p, n);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return false;
    p += r;
    n -= size_t(r);
  }
  return true;
}

// A task's frame: length (8 bytes), then the task. A reply's: kind (1 byte:
// 0 ok, 1 failed), status (4 bytes), length (8 bytes), then the text. The
// numbers are little-endian (util/byte_codec.h).
constexpr size_t kReplyHead = 1 + 4 + 8;

/// The worker's loop; never returns.
[[noreturn]] void serve_tasks(const WorkerPool::Serve& serve, int in, int out) {
  for (;;) {
    uint8_t len_bytes[8];
    if (!read_all(in, len_bytes, 8)) break;  // the parent closed the pool
    std::string task(size_t(get_u64(len_bytes)), '\0');
    if (!read_all(in, task.data(), task.size())) break;
    uint8_t kind = 0;
    int32_t status = 0;
    std::string reply;
    try {
      reply = serve(task);
    } catch (...) {
      const ErrorVerdict v = classify_current_exception();
      kind = 1;
      status = v.status;
      reply = v.what;
    }
    uint8_t head[kReplyHead];
    head[0] = kind;
    put_u32(head + 1, uint32_t(status));
    put_u64(head + 5, reply.size());
    if (!write_all(out, head, sizeof head) || !write_all(out, reply.data(), reply.size())) break;
  }
  std::fflush(nullptr);
  _exit(0);
}

std::string describe_status(int st) {
  if (WIFSIGNALED(st)) return "killed by signal " + std::to_string(WTERMSIG(st)) + " (" + strsignal(WTERMSIG(st)) + ")";
  return "stopped (exit status " + std::to_string(WIFEXITED(st) ? WEXITSTATUS(st) : -1) + ")";
}

}  // namespace

WorkerPool::WorkerPool(size_t n, Serve serve, std::function<void()> at_start) : workers_(n) {
  invariant(n >= 1, "a worker pool has a worker");
  // A write to a worker that died fails (EPIPE) instead of killing the caller.
  std::signal(SIGPIPE, SIG_IGN);
  std::fflush(nullptr);  // no buffered output is written twice
  for (size_t i = 0; i < n; ++i) {
    int down[2], up[2];
    if (::pipe(down) != 0) throw UserError(std::string("cannot create a pipe for a worker: ") + std::strerror(errno));
    if (::pipe(up) != 0) {
      const int e = errno;
      ::close(down[0]);
      ::close(down[1]);
      throw UserError(std::string("cannot create a pipe for a worker: ") + std::strerror(e));
    }
    const pid_t pid = ::fork();
    if (pid < 0) {
      const int e = errno;
      for (int fd : {down[0], down[1], up[0], up[1]}) ::close(fd);
      throw UserError(std::string("cannot start a worker process: ") + std::strerror(e));
    }
    if (pid == 0) {
      ::close(down[1]);
      ::close(up[0]);
      for (size_t j = 0; j < i; ++j) {
        ::close(workers_[j].to);
        ::close(workers_[j].from);
      }
      if (at_start) at_start();
      serve_tasks(serve, down[0], up[1]);
    }
    ::close(down[0]);
    ::close(up[1]);
    workers_[i].pid = pid;
    workers_[i].to = down[1];
    workers_[i].from = up[0];
  }
}

WorkerPool::~WorkerPool() {
  // Left early (an error in the caller): a worker's task is abandoned.
  for (Worker& w : workers_)
    if (w.pid > 0 && w.busy) ::kill(w.pid, SIGKILL);
  close();
}

bool WorkerPool::any_alive() const {
  for (const Worker& w : workers_)
    if (w.pid > 0) return true;
  return false;
}

bool WorkerPool::any_busy() const {
  for (const Worker& w : workers_)
    if (w.pid > 0 && w.busy) return true;
  return false;
}

void WorkerPool::send(size_t i, const std::string& task) {
  Worker& w = workers_.at(i);
  invariant(w.pid > 0 && !w.busy, "a task goes to an idle worker");
  uint8_t len[8];
  put_u64(len, task.size());
  w.busy = true;
  // A worker that died cannot take it: next() reports its death.
  if (!write_all(w.to, len, 8)) return;
  write_all(w.to, task.data(), task.size());
}

void WorkerPool::reap(Worker& w, int* status) {
  if (w.to >= 0) ::close(w.to);
  if (w.from >= 0) ::close(w.from);
  int st = 0;
  rusage ru{};
  while (::wait4(w.pid, &st, 0, &ru) < 0 && errno == EINTR) {
  }
  cpu_seconds_ += double(ru.ru_utime.tv_sec) + 1e-6 * double(ru.ru_utime.tv_usec) + double(ru.ru_stime.tv_sec) +
                  1e-6 * double(ru.ru_stime.tv_usec);
  if (status) *status = st;
  w.pid = -1;
  w.to = w.from = -1;
  w.busy = false;
}

WorkerPool::Reply WorkerPool::next() {
  std::vector<char> buf(1 << 16);
  for (;;) {
    // A whole reply already read?
    for (size_t i = 0; i < workers_.size(); ++i) {
      Worker& w = workers_[i];
      if (w.pid <= 0 || !w.busy || w.in.size() < kReplyHead) continue;
      const auto* head = reinterpret_cast<const uint8_t*>(w.in.data());
      const uint64_t len = get_u64(head + 5);
      if (w.in.size() < kReplyHead + len) continue;
      Reply r;
      r.worker = i;
      r.kind = head[0] ? Reply::Kind::kFailed : Reply::Kind::kOk;
      r.status = int32_t(get_u32(head + 1));
      r.text = w.in.substr(kReplyHead, size_t(len));
      w.in.erase(0, kReplyHead + size_t(len));
      w.busy = false;
      return r;
    }
    std::vector<pollfd> fds;
    std::vector<size_t> who;
    for (size_t i = 0; i < workers_.size(); ++i)
      if (workers_[i].pid > 0 && workers_[i].busy) {
        fds.push_back(pollfd{workers_[i].from, POLLIN, 0});
        who.push_back(i);
      }
    invariant(!fds.empty(), "a worker pool waits for a reply only while a worker holds a task");
    if (::poll(fds.data(), fds.size(), -1) < 0) {
      if (errno == EINTR) continue;
      throw UserError(std::string("worker pool: poll: ") + std::strerror(errno));
    }
    for (size_t k = 0; k < fds.size(); ++k) {
      if (!(fds[k].revents & (POLLIN | POLLHUP | POLLERR))) continue;
      Worker& w = workers_[who[k]];
      const ssize_t n = ::read(w.from, buf.data(), buf.size());
      if (n < 0 && errno == EINTR) continue;
      if (n > 0) {
        w.in.append(buf.data(), size_t(n));
        continue;
      }
      // The worker died holding its task.
      int st = 0;
      reap(w, &st);
      Reply r;
      r.worker = who[k];
      r.kind = Reply::Kind::kDied;
      r.text = describe_status(st);
      return r;
    }
  }
}

double WorkerPool::close() {
  // Closing every worker's task pipe first ends their loops together; then
  // each is reaped.
  for (Worker& w : workers_)
    if (w.pid > 0 && w.to >= 0) {
      ::close(w.to);
      w.to = -1;
    }
  for (Worker& w : workers_)
    if (w.pid > 0) reap(w, nullptr);
  return cpu_seconds_;
}

}  // namespace ropsim
