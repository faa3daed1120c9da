// The output discipline of output_file.h in one file: the temporary files,
// the targets written in place (FIFOs, devices), the created-target list and
// the fatal-signal handler that removes pending temporaries. They stay
// together because the handler must see every state an OutputFile passes
// through (the pending registry is this file's own, async-signal-safe).
#include "util/output_file.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>
#include <vector>

#include "util/errors.h"

namespace ropsim {

namespace {

// ------------------------------------------------ pending temporary files
// Kept in fixed storage so a signal handler can unlink them (unlink and rmdir
// are async-signal-safe; nothing here allocates in the handler).
constexpr int kPendingSlots = 64;
constexpr size_t kPendingPath = 4096;
char g_pending[kPendingSlots][kPendingPath];
volatile sig_atomic_t g_pending_kind[kPendingSlots];  // 0 free, 1 file, 2 folder
std::mutex g_pending_mutex;

int add_pending(const std::string& p, int kind) {
  if (p.size() >= kPendingPath) return -1;
  std::lock_guard<std::mutex> lock(g_pending_mutex);
  for (int i = 0; i < kPendingSlots; ++i)
    if (!g_pending_kind[i]) {
      std::memcpy(g_pending[i], p.c_str(), p.size() + 1);
      g_pending_kind[i] = kind;
      return i;
    }
  return -1;  // no slot: the file is still removed on every path but a signal
}

void drop_pending(const std::string& p) {
  std::lock_guard<std::mutex> lock(g_pending_mutex);
  for (int i = 0; i < kPendingSlots; ++i)
    if (g_pending_kind[i] && p == g_pending[i]) g_pending_kind[i] = 0;
}

void remove_pending() {
  for (int pass = 1; pass <= 2; ++pass)  // files first, then their folders
    for (int i = 0; i < kPendingSlots; ++i)
      if (g_pending_kind[i] == pass) pass == 1 ? (void)::unlink(g_pending[i]) : (void)::rmdir(g_pending[i]);
}

/// Dies of sig with its default action (after the handler's cleanup).
[[noreturn]] void die_of(int sig) {
  ::signal(sig, SIG_DFL);
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, sig);
  ::sigprocmask(SIG_UNBLOCK, &set, nullptr);
  ::raise(sig);
  ::_exit(128 + sig);  // not reached: the default action of every signal used here ends the process
}

extern "C" void on_fatal_signal(int sig) {
  remove_pending();
  die_of(sig);
}

/// Standard output's reader closed it: end as a pipeline's writer does, by
/// SIGPIPE (no message; the shell's status 141), the temporary files removed.
[[noreturn]] void die_of_closed_stdout() {
  std::fflush(stderr);
  remove_pending();
  die_of(SIGPIPE);
}

/// Seconds to wait for a FIFO's reader; negative: forever.
std::atomic<double> g_output_timeout{-1.0};

// ------------------------------------------------ targets this run created
struct Created {
  std::string path;
  dev_t dev;
  ino_t ino;
};
std::vector<Created> g_created;
std::vector<std::string> g_created_dirs;  ///< by ensure_parent_dir, outermost first
std::mutex g_created_mutex;

/// The mode of a new file: what open(..., 0666) would give it.
mode_t new_file_mode() { return 0666 & ~current_umask(); }

std::string base_of(const std::string& p) {
  const auto slash = p.find_last_of('/');
  return slash == std::string::npos ? p : p.substr(slash + 1);
}

std::string temp_dir() {
  const char* t = std::getenv("TMPDIR");
  return t && *t ? t : "/tmp";
}

/// mkstemps on DIR/.BASE.XXXXXX<suffix>; returns the fd, sets name.
int make_temp(const std::string& dir, std::string base, const std::string& suffix, std::string& name) {
  if (base.size() > 200) base.resize(200);  // NAME_MAX is 255
  std::string tmpl = dir + "/." + base + ".XXXXXX" + suffix;
  std::vector<char> buf(tmpl.begin(), tmpl.end());
  buf.push_back('\0');
  const int fd = ::mkstemps(buf.data(), int(suffix.size()));
  if (fd >= 0) {
    ::fcntl(fd, F_SETFD, FD_CLOEXEC);
    name = buf.data();
  }
  return fd;
}

bool write_all(int fd, const char* p, size_t n) {
  while (n) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    p += w;
    n -= size_t(w);
  }
  return true;
}

}  // namespace

// ------------------------------------------------ the FIFO for by-name writers
struct OutputFile::Pipe {
  std::string dir, fifo;
  std::thread reader;
  std::atomic<bool> done{false};
  int err = 0;  ///< first error copying into the output (written by the reader)

  /// Unblocks a reader still waiting for a writer to open the FIFO, then joins.
  void finish() {
    while (!done.load()) {
      const int fd = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC);
      if (fd >= 0) ::close(fd);
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    if (reader.joinable()) reader.join();
  }
  void remove() {
    ::unlink(fifo.c_str());
    ::rmdir(dir.c_str());
    drop_pending(fifo);
    drop_pending(dir);
  }
};

// ------------------------------------------------ OutputFile

OutputFile::OutputFile(std::string path) : OutputFile(std::move(path), Options{}) {}

OutputFile::OutputFile(std::string path, Options opt) : path_(std::move(path)), opt_(std::move(opt)) {
  if (path_.empty()) throw UserError("an output file name is empty");
  const bool by_name = opt_.named && !opt_.via_pipe;  // the library writes write_name_ itself
  if (path_ == "-") {
    if (!opt_.allow_stdout) throw UserError("-: standard output is not an option for this output; give a file name");
    mode_ = Mode::kStdout;
  } else {
    target_ = resolve_symlinks(path_);
    struct stat st;
    if (::stat(target_.c_str(), &st) == 0) {
      existed_ = true;
      if (S_ISDIR(st.st_mode)) fail_errno(EISDIR);
      if (S_ISREG(st.st_mode)) {
        mode_ = Mode::kReplace;
        target_mode_ = int(st.st_mode & 07777);
      } else {
        mode_ = Mode::kInPlace;
      }
    } else if (errno != ENOENT) {
      fail_errno(errno);
    }
  }
  if (by_name) {
    // Replace: next to the target, so the rename stays in one file system.
    // In place / stdout: in $TMPDIR, then copied (never a temporary in /dev).
    const bool beside = mode_ == Mode::kReplace;
    const int fd =
        make_temp(beside ? folder_of(target_) : temp_dir(), beside ? base_of(target_) : "ropsim", opt_.suffix, temp_);
    if (fd < 0) fail_errno(errno);
    add_pending(temp_, 1);
    ::close(fd);
    write_name_ = temp_;
    return;
  }
  if (mode_ == Mode::kStdout) {
    f_ = stdout;
  } else if (mode_ == Mode::kInPlace) {
    const int fd = open_in_place();
    f_ = ::fdopen(fd, "wb");
    if (!f_) {
      const int e = errno;
      ::close(fd);
      fail_errno(e);
    }
  } else {
    const int fd = make_temp(folder_of(target_), base_of(target_), "", temp_);
    if (fd < 0) fail_errno(errno);
    add_pending(temp_, 1);
    f_ = ::fdopen(fd, "wb");
    if (!f_) {
      const int e = errno;
      ::close(fd);
      fail_errno(e);
    }
  }
  if (opt_.via_pipe) {
    pipe_ = std::make_unique<Pipe>();
    std::string tmpl = temp_dir() + "/ropsim-pipe.XXXXXX";
    std::vector<char> buf(tmpl.begin(), tmpl.end());
    buf.push_back('\0');
    if (!::mkdtemp(buf.data())) fail_errno(errno);
    pipe_->dir = buf.data();
    add_pending(pipe_->dir, 2);
    pipe_->fifo = pipe_->dir + "/output" + opt_.suffix;
    if (::mkfifo(pipe_->fifo.c_str(), 0600) != 0) {
      const int e = errno;
      ::rmdir(pipe_->dir.c_str());
      drop_pending(pipe_->dir);
      pipe_.reset();
      fail_errno(e);
    }
    add_pending(pipe_->fifo, 1);
    write_name_ = pipe_->fifo;
    Pipe* p = pipe_.get();
    FILE* out = f_;
    p->reader = std::thread([p, out] {
      const int fd = ::open(p->fifo.c_str(), O_RDONLY | O_CLOEXEC);  // waits for the writer
      if (fd < 0) {
        p->err = errno;
      } else {
        std::vector<char> buf(1 << 16);
        for (;;) {
          const ssize_t r = ::read(fd, buf.data(), buf.size());
          if (r < 0 && errno == EINTR) continue;
          if (r < 0) {
            if (!p->err) p->err = errno;
            break;
          }
          if (r == 0) break;
          // After an error keep draining, so the writer never blocks.
          if (!p->err && std::fwrite(buf.data(), 1, size_t(r), out) != size_t(r)) p->err = errno ? errno : EIO;
        }
        ::close(fd);
      }
      p->done.store(true);
    });
  }
}

OutputFile::~OutputFile() {
  if (!committed_) discard();
}

FILE* OutputFile::stream() {
  if (!f_ || (opt_.named && !opt_.via_pipe)) throw InternalError("OutputFile::stream() on a by-name output");
  return f_;
}

void OutputFile::write(const void* data, size_t n) {
  FILE* f = stream();
  errno = 0;
  if (n && std::fwrite(data, 1, n, f) != n) fail_errno(errno ? errno : EIO);
}

void OutputFile::fail(const std::string& what) {
  discard();
  throw UserError((path_ == "-" ? std::string("standard output") : path_) + ": " + what);
}

void OutputFile::fail_errno(int err) {
  if (err == EPIPE) {
    if (mode_ == Mode::kStdout) {
      discard();
      die_of_closed_stdout();
    }
    fail("the reader closed it");
  }
  discard();
  // A SystemError carries errno, so a study tells a host fault (ENOSPC, EIO)
  // from a bad input.
  throw SystemError((path_ == "-" ? std::string("standard output") : path_) + ": " + std::strerror(err), err);
}

int OutputFile::open_in_place() {
  struct stat st;
  const bool fifo = ::stat(target_.c_str(), &st) == 0 && S_ISFIFO(st.st_mode);
  if (!fifo) {
    const int fd = ::open(target_.c_str(), O_WRONLY | O_NOCTTY | O_CLOEXEC);
    if (fd < 0) fail_errno(errno);
    return fd;
  }
  // A FIFO: a blocking open would wait for a reader without a word and
  // without end. Open it without blocking (ENXIO: no reader yet) and retry.
  const double timeout = g_output_timeout.load();
  const auto t0 = std::chrono::steady_clock::now();
  auto pause = std::chrono::microseconds(500);
  bool said = false;
  for (;;) {
    const int fd = ::open(target_.c_str(), O_WRONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
    if (fd >= 0) {
      // Written like any file from here on: writes wait for the reader.
      const int flags = ::fcntl(fd, F_GETFL);
      if (flags < 0 || ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK) != 0) {
        const int e = errno;
        ::close(fd);
        fail_errno(e);
      }
      return fd;
    }
    if (errno == EINTR) continue;
    if (errno != ENXIO) fail_errno(errno);
    const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (timeout >= 0 && waited >= timeout) {
      char secs[32];
      std::snprintf(secs, sizeof secs, "%g", timeout);
      fail(std::string("no reader opened it within ") + secs + " s (--output-timeout)");
    }
    if (!said) {
      std::fprintf(stderr, "ropsim: waiting for a reader of %s\n", path_.c_str());
      std::fflush(stderr);
      said = true;
    }
    auto step = pause;
    if (timeout >= 0) {
      const auto left =
          std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::duration<double>(timeout - waited));
      if (left < step) step = left;
    }
    std::this_thread::sleep_for(step);
    pause = std::min<std::chrono::microseconds>(pause * 2, std::chrono::milliseconds(50));
  }
}

void OutputFile::discard() noexcept {
  if (pipe_) {
    pipe_->finish();
    pipe_->remove();
    pipe_.reset();
  }
  if (f_ && f_ != stdout) std::fclose(f_);
  f_ = nullptr;
  if (!temp_.empty()) {
    ::unlink(temp_.c_str());
    drop_pending(temp_);
    temp_.clear();
  }
}

bool OutputFile::patch(uint64_t offset, const void* data, size_t n) {
  if (!can_patch()) return false;
  errno = 0;
  if (std::fflush(f_) != 0) fail_errno(errno ? errno : EIO);
  const auto* b = static_cast<const uint8_t*>(data);
  for (size_t done = 0; done < n;) {
    const ssize_t w = ::pwrite(fileno(f_), b + done, n - done, off_t(offset + done));
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) fail_errno(w < 0 ? errno : EIO);
    done += size_t(w);
  }
  return true;
}

void OutputFile::commit() {
  if (committed_) return;
  if (pipe_) {
    pipe_->finish();
    const int err = pipe_->err;
    pipe_->remove();
    pipe_.reset();
    if (err) fail_errno(err);
  }
  if (opt_.named && !opt_.via_pipe)
    commit_named();
  else
    commit_stream();
  committed_ = true;
}

void OutputFile::commit_stream() {
  errno = 0;
  if (std::fflush(f_) != 0) fail_errno(errno ? errno : EIO);
  if (std::ferror(f_)) fail_errno(EIO);  // a write through stream() failed
  if (mode_ == Mode::kStdout) {
    f_ = nullptr;
    return;
  }
  const int fd = ::fileno(f_);
  if (mode_ == Mode::kReplace) {
    if (::fsync(fd) != 0) fail_errno(errno);
    ::fchmod(fd, target_mode_ >= 0 ? mode_t(target_mode_) : new_file_mode());
  }
  FILE* f = f_;
  f_ = nullptr;
  if (std::fclose(f) != 0) fail_errno(errno);
  if (mode_ == Mode::kReplace) rename_onto_target(-1);
}

void OutputFile::commit_named() {
  struct stat st;
  if (::stat(temp_.c_str(), &st) != 0) fail_errno(errno);
  if (st.st_size == 0) fail("the writer produced an empty file");
  const int fd = ::open(temp_.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) fail_errno(errno);
  if (mode_ == Mode::kReplace) {
    if (::fsync(fd) != 0) {
      const int e = errno;
      ::close(fd);
      fail_errno(e);
    }
    ::fchmod(fd, target_mode_ >= 0 ? mode_t(target_mode_) : new_file_mode());
    ::close(fd);
    rename_onto_target(-1);
    return;
  }
  // In place or stdout: copy the bytes into the target.
  int out = -1;
  try {
    out = mode_ == Mode::kStdout ? ::dup(1) : open_in_place();
  } catch (...) {
    ::close(fd);
    throw;
  }
  if (out < 0) {
    const int e = errno;
    ::close(fd);
    fail_errno(e);
  }
  if (mode_ == Mode::kStdout) std::fflush(stdout);
  std::vector<char> buf(1 << 16);
  int err = 0;
  for (;;) {
    const ssize_t r = ::read(fd, buf.data(), buf.size());
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) err = errno;
    if (r <= 0) break;
    if (!write_all(out, buf.data(), size_t(r))) {
      err = errno;
      break;
    }
  }
  ::close(fd);
  if (::close(out) != 0 && !err) err = errno;
  if (err) fail_errno(err);
  ::unlink(temp_.c_str());
  drop_pending(temp_);
  temp_.clear();
}

void OutputFile::rename_onto_target(int) {
  if (::rename(temp_.c_str(), target_.c_str()) != 0) fail_errno(errno);
  drop_pending(temp_);
  temp_.clear();
  // Make the rename durable (best effort: some file systems refuse fsync on a folder).
  const int dfd = ::open(folder_of(target_).c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
  struct stat st;
  if (!existed_ && ::lstat(target_.c_str(), &st) == 0) {
    std::lock_guard<std::mutex> lock(g_created_mutex);
    g_created.push_back({target_, st.st_dev, st.st_ino});
  }
}

// ------------------------------------------------ helpers

void write_text_output(const std::string& path, std::string_view text, bool allow_stdout) {
  OutputFile::Options o;
  o.allow_stdout = allow_stdout;
  OutputFile out(path, o);
  out.write(text);
  out.commit();
}

void ensure_parent_dir(const std::string& path) {
  if (path == "-") return;
  const std::filesystem::path p(path);
  if (!p.has_parent_path()) return;
  // Each missing folder, outermost first, made by this call's own mkdir: a
  // folder a concurrent run made is not this run's to remove.
  std::vector<std::filesystem::path> missing;
  for (std::filesystem::path d = p.parent_path(); !d.empty(); d = d.parent_path()) {
    struct stat st;
    if (::lstat(d.c_str(), &st) == 0) break;
    missing.insert(missing.begin(), d);
    if (d == d.parent_path()) break;
  }
  for (const auto& d : missing) {
    if (::mkdir(d.c_str(), 0777) == 0) {
      std::lock_guard<std::mutex> lock(g_created_mutex);
      g_created_dirs.push_back(d.string());
    } else if (errno != EEXIST) {
      throw UserError(path + ": cannot create the folder " + p.parent_path().string() + ": " + std::strerror(errno));
    }
  }
  // What mkdir could not say (a component that is a file, a symlink to a folder...).
  std::error_code ec;
  std::filesystem::create_directories(p.parent_path(), ec);
  if (ec) throw UserError(path + ": cannot create the folder " + p.parent_path().string() + ": " + ec.message());
}

int remove_created_outputs() noexcept {
  std::lock_guard<std::mutex> lock(g_created_mutex);
  int n = 0;
  for (const auto& c : g_created) {
    struct stat st;
    // Only the file this run wrote: a concurrent run may have replaced it since.
    if (::lstat(c.path.c_str(), &st) == 0 && st.st_dev == c.dev && st.st_ino == c.ino && ::unlink(c.path.c_str()) == 0)
      ++n;
  }
  g_created.clear();
  // Then the folders made for them, deepest first; rmdir keeps any that holds something.
  for (auto it = g_created_dirs.rbegin(); it != g_created_dirs.rend(); ++it) ::rmdir(it->c_str());
  g_created_dirs.clear();
  return n;
}

void forget_created_outputs() noexcept {
  std::lock_guard<std::mutex> lock(g_created_mutex);
  g_created.clear();
  g_created_dirs.clear();
}

void install_output_signal_handling() {
  ::signal(SIGXFSZ, SIG_IGN);
  ::signal(SIGPIPE, SIG_IGN);
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
    struct sigaction sa {};
    sa.sa_handler = on_fatal_signal;
    sigemptyset(&sa.sa_mask);
    ::sigaction(sig, &sa, nullptr);
  }
}

void set_output_timeout(double seconds) { g_output_timeout.store(std::isfinite(seconds) ? seconds : -1.0); }

void finish_standard_output() {
  errno = 0;
  const bool flush_failed = std::fflush(stdout) != 0;
  int err = flush_failed ? errno : 0;
  if (!flush_failed && !std::ferror(stdout)) return;
  if (!err) {
    // An earlier write failed (stdio keeps only the flag): a pipe or socket
    // whose reader is gone shows POLLERR; anything else is an I/O error.
    struct stat st;
    pollfd pf{1, POLLOUT, 0};
    err = ::fstat(1, &st) == 0 && (S_ISFIFO(st.st_mode) || S_ISSOCK(st.st_mode)) && ::poll(&pf, 1, 0) == 1 &&
                  (pf.revents & POLLERR)
              ? EPIPE
              : EIO;
  }
  standard_output_failed(err);
}

void standard_output_failed(int err) {
  if (err == EPIPE) die_of_closed_stdout();
  std::clearerr(stdout);
  throw UserError(std::string("standard output: ") + std::strerror(err ? err : EIO));
}

mode_t current_umask() {
  // Linux 4.7 and later tell it in /proc; umask() would set it for a moment,
  // giving a file another thread creates meanwhile the mode 0666.
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);)
    if (line.rfind("Umask:", 0) == 0) return mode_t(std::strtoul(line.c_str() + 6, nullptr, 8)) & 0777;
  static std::mutex m;
  std::lock_guard<std::mutex> lock(m);
  const mode_t u = ::umask(022);
  ::umask(u);
  return u;
}

}  // namespace ropsim
