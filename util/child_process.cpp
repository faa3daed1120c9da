#include "util/child_process.h"

#include <fcntl.h>
#include <poll.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <thread>

#include "util/errors.h"

extern char** environ;

namespace ropsim {

namespace {

using Clock = std::chrono::steady_clock;

bool is_executable_file(const std::string& p) {
  struct stat st;
  return ::stat(p.c_str(), &st) == 0 && S_ISREG(st.st_mode) && ::access(p.c_str(), X_OK) == 0;
}

/// Writes all of n bytes, retrying on EINTR (async-signal-safe: the child
/// between fork and exec uses it).
void write_fully(int fd, const void* p, size_t n) {
  const char* c = static_cast<const char*>(p);
  while (n) {
    const ssize_t w = ::write(fd, c, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return;
    c += w;
    n -= size_t(w);
  }
}

ChildExit exit_of(int status) {
  ChildExit e;
  if (WIFSIGNALED(status)) {
    e.signaled = true;
    e.signal = WTERMSIG(status);
  } else {
    e.code = WEXITSTATUS(status);
  }
  return e;
}

volatile sig_atomic_t g_stop_signal = 0;
constexpr int kStopSignals[3] = {SIGINT, SIGTERM, SIGHUP};

extern "C" void on_stop_signal(int sig) { g_stop_signal = sig; }

}  // namespace

std::string ChildExit::describe() const {
  if (!signaled) return "exited with status " + std::to_string(code);
  const char* name = ::strsignal(signal);
  return "was killed by signal " + std::to_string(signal) + (name ? std::string(" (") + name + ")" : "");
}

std::string find_executable(const std::string& name) {
  if (name.empty()) return "";
  if (name.find('/') != std::string::npos) return is_executable_file(name) ? name : "";
  const char* path = std::getenv("PATH");
  std::string dirs = path ? path : "/usr/local/bin:/usr/bin:/bin";
  size_t at = 0;
  for (;;) {
    const size_t end = dirs.find(':', at);
    std::string dir = dirs.substr(at, end == std::string::npos ? std::string::npos : end - at);
    if (dir.empty()) dir = ".";
    const std::string candidate = dir + "/" + name;
    if (is_executable_file(candidate)) return candidate;
    if (end == std::string::npos) return "";
    at = end + 1;
  }
}

std::vector<std::string> environment_with(const std::vector<std::pair<std::string, std::string>>& set,
                                          const std::vector<std::string>& unset) {
  auto named = [](const std::string& entry, const std::string& name) {
    return entry.size() > name.size() && entry.compare(0, name.size(), name) == 0 && entry[name.size()] == '=';
  };
  std::vector<std::string> env;
  for (char** e = environ; e && *e; ++e) {
    const std::string entry = *e;
    bool drop = false;
    for (const auto& [name, value] : set) drop = drop || named(entry, name);
    for (const auto& name : unset) drop = drop || named(entry, name);
    if (!drop) env.push_back(entry);
  }
  for (const auto& [name, value] : set) env.push_back(name + "=" + value);
  return env;
}

// ------------------------------------------------ ChildProcess

ChildProcess::ChildProcess(const Spec& spec) {
  if (spec.argv.empty()) throw InternalError("ChildProcess: an empty argv");
  // Everything the child needs is prepared here: between fork and exec only
  // async-signal-safe calls are allowed.
  std::vector<char*> argv, envp;
  for (const auto& a : spec.argv) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  for (const auto& e : spec.env) envp.push_back(const_cast<char*>(e.c_str()));
  envp.push_back(nullptr);
  char** const env = spec.env.empty() ? environ : envp.data();

  const int out =
      ::open(spec.output.empty() ? "/dev/null" : spec.output.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (out < 0) {
    const int e = errno;
    throw SystemError((spec.output.empty() ? "/dev/null" : spec.output) + ": " + std::strerror(e), e);
  }
  const int in = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
  int report[2];  // the exec's errno, or EOF when the exec succeeded (close-on-exec)
  if (in < 0 || ::pipe2(report, O_CLOEXEC) != 0) {
    const int e = errno;
    ::close(out);
    if (in >= 0) ::close(in);
    throw SystemError(std::string("cannot make a pipe: ") + std::strerror(e), e);
  }
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid < 0) {
    const int e = errno;
    for (int fd : {out, in, report[0], report[1]}) ::close(fd);
    throw SystemError(std::string("cannot start ") + spec.argv[0] + ": " + std::strerror(e), e);
  }
  if (pid == 0) {
    ::setpgid(0, 0);
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(127);  // the parent died before the line above
    for (int sig : kStopSignals) ::signal(sig, SIG_DFL);
    ::signal(SIGPIPE, SIG_DFL);
    ::signal(SIGXFSZ, SIG_DFL);
    sigset_t none;
    sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
    ::dup2(in, 0);
    ::dup2(out, 1);
    ::dup2(out, 2);
    if (spec.keep_fd >= 0) ::fcntl(spec.keep_fd, F_SETFD, 0);  // survives the exec
    ::execve(argv[0], argv.data(), env);
    const int e = errno;
    write_fully(report[1], &e, sizeof e);
    ::_exit(127);
  }
  ::setpgid(pid, pid);  // also here: the group exists before either side goes on
  pid_ = pid;
  for (int fd : {out, in, report[1]}) ::close(fd);
  int err = 0;
  ssize_t r;
  do r = ::read(report[0], &err, sizeof err);
  while (r < 0 && errno == EINTR);
  ::close(report[0]);
  if (r == ssize_t(sizeof err)) {
    stop();
    throw UserError("cannot run " + spec.argv[0] + ": " + std::strerror(err));
  }
}

ChildProcess::~ChildProcess() { stop(); }

std::optional<ChildExit> ChildProcess::poll() {
  if (exit_) return exit_;
  // Seen without reaping first, so the group id cannot be reused while the
  // rest of the group (what the child started) is killed.
  siginfo_t info{};
  if (::waitid(P_PID, id_t(pid_), &info, WEXITED | WNOHANG | WNOWAIT) != 0 || info.si_pid == 0) return std::nullopt;
  ::kill(-pid_, SIGKILL);
  int status = 0;
  while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
  }
  exit_ = exit_of(status);
  return exit_;
}

std::optional<ChildExit> ChildProcess::wait_until(Clock::time_point deadline, const volatile sig_atomic_t* stop) {
  for (;;) {
    if (auto e = poll()) return e;
    if ((stop && *stop) || Clock::now() >= deadline) return std::nullopt;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

ChildExit ChildProcess::stop(std::chrono::milliseconds grace) noexcept {
  if (pid_ < 0) return ChildExit{};
  if (exit_) return *exit_;
  if (auto e = poll()) return *e;
  ::kill(-pid_, SIGTERM);
  const auto deadline = Clock::now() + grace;
  while (Clock::now() < deadline) {
    if (auto e = poll()) return *e;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ::kill(-pid_, SIGKILL);
  int status = 0;
  while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
  }
  exit_ = exit_of(status);
  return *exit_;
}

// ------------------------------------------------ StopSignals

StopSignals::StopSignals() {
  g_stop_signal = 0;
  for (int i = 0; i < 3; ++i) {
    struct sigaction sa {};
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    ::sigaction(kStopSignals[i], &sa, &old_[i]);
  }
}

StopSignals::~StopSignals() { restore(); }

void StopSignals::restore() noexcept {
  if (restored_) return;
  restored_ = true;
  for (int i = 0; i < 3; ++i) ::sigaction(kStopSignals[i], &old_[i], nullptr);
}

const volatile sig_atomic_t* StopSignals::flag() const { return &g_stop_signal; }

int StopSignals::caught() const { return g_stop_signal; }

void StopSignals::reraise() {
  const int sig = g_stop_signal;
  if (!sig) return;
  restore();
  ::raise(sig);
  // A previous handler that returns (SIG_IGN, or one that does not end the
  // process): end as the signal's default action would.
  ::signal(sig, SIG_DFL);
  ::raise(sig);
  ::_exit(128 + sig);
}

// ------------------------------------------------ VirtualDisplay

VirtualDisplay::VirtualDisplay(const std::string& xvfb, unsigned width, unsigned height, const std::string& log,
                               std::chrono::milliseconds timeout, const volatile sig_atomic_t* stop) {
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) {
    const int e = errno;
    throw SystemError(std::string("cannot make a pipe: ") + std::strerror(e), e);
  }
  ChildProcess::Spec spec;
  spec.argv = {xvfb,        "-displayfd", std::to_string(fds[1]),
               "-screen",   "0",          std::to_string(width) + "x" + std::to_string(height) + "x24",
               "-nolisten", "tcp",        "-noreset"};
  spec.output = log;
  spec.keep_fd = fds[1];
  try {
    server_.emplace(spec);
  } catch (...) {
    ::close(fds[0]);
    ::close(fds[1]);
    throw;
  }
  ::close(fds[1]);
  const auto deadline = Clock::now() + timeout;
  std::string text;
  std::string failure;
  for (;;) {
    if (text.find('\n') != std::string::npos) break;
    if (stop && *stop) {
      failure = "interrupted";
      break;
    }
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) {
      failure = "did not start within " + std::to_string(timeout.count()) + " ms";
      break;
    }
    pollfd pf{fds[0], POLLIN, 0};
    const int n = ::poll(&pf, 1, int(std::min<long long>(left, 50)));
    if (n < 0 && errno == EINTR) continue;
    if (n > 0) {
      char buf[64];
      const ssize_t r = ::read(fds[0], buf, sizeof buf);
      if (r > 0) {
        text.append(buf, size_t(r));
        continue;
      }
      if (r == 0) {  // the server closed its end without a number: it ended
        server_->wait_until(Clock::now() + std::chrono::seconds(2), nullptr);
        const auto e = server_->exit();
        failure = e ? e->describe() : "closed its -displayfd pipe";
        break;
      }
    }
  }
  ::close(fds[0]);
  if (!failure.empty()) {
    const std::string said = last_line_of(log);
    server_->stop();
    throw UserError(xvfb + " (the virtual X server) " + failure + (said.empty() ? "" : ": " + said));
  }
  display_ = ":" + text.substr(0, text.find('\n'));
}

std::string last_line_of(const std::string& path, size_t max_chars) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return "";
  f.seekg(0, std::ios::end);
  const std::streamoff size = f.tellg();
  const std::streamoff from = size > 4096 ? size - 4096 : 0;
  f.seekg(from);
  std::string tail((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  while (!tail.empty() && (tail.back() == '\n' || tail.back() == '\r' || tail.back() == ' ')) tail.pop_back();
  const size_t nl = tail.rfind('\n');
  std::string line = nl == std::string::npos ? tail : tail.substr(nl + 1);
  for (char& c : line)
    if (static_cast<unsigned char>(c) < 0x20) c = ' ';
  if (line.size() > max_chars) line = "..." + line.substr(line.size() - max_chars);
  return line;
}

}  // namespace ropsim
