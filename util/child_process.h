// Child processes a command starts and must stop again, whatever happens: a
// virtual X server, an application under test, a trace replayer
// (`ropsim capture gl`, docs/capture.md).
//
//  - Each child runs in a process group of its own (its pid), so that
//    stopping it also stops what it started, and a Ctrl-C at the terminal
//    reaches ropsim alone, which then stops its children itself.
//  - The child dies with ropsim (PR_SET_PDEATHSIG): a ropsim killed by
//    SIGKILL leaves no child running.
//  - A failed exec (no such file, not executable) is the UserError
//    "cannot run PROGRAM: <reason>" in the parent, not a child that exits 127.
//  - ~ChildProcess stops the group (SIGTERM, a grace period, SIGKILL) and
//    reaps the child: no path leaves a process or a zombie behind.
//  - StopSignals turns SIGINT, SIGTERM and SIGHUP into a flag the waits
//    watch, so the command can stop its children, clean up, and then die of
//    the signal as it would have (reraise()).
//
// Bottom layer: POSIX and the standard library only.
#pragma once
#include <sys/types.h>

#include <chrono>
#include <csignal>
#include <optional>
#include <string>
#include <vector>

namespace ropsim {

/// How a child ended.
struct ChildExit {
  bool signaled = false;
  int code = 0;    ///< exit status (when !signaled)
  int signal = 0;  ///< the signal that ended it (when signaled)
  /// "exited with status 3", "was killed by signal 11 (Segmentation fault)".
  std::string describe() const;
  bool success() const { return !signaled && code == 0; }
};

/// name when it contains '/', else the first executable regular file
/// PATH/name; "" when there is none (or name is not an executable file).
std::string find_executable(const std::string& name);

/// The calling process's environment, "NAME=value" each, with the given
/// variables set (replacing their earlier values) and those in unset removed.
std::vector<std::string> environment_with(const std::vector<std::pair<std::string, std::string>>& set,
                                          const std::vector<std::string>& unset = {});

class ChildProcess {
 public:
  struct Spec {
    /// argv[0] is a path (find_executable's result), the rest its arguments.
    std::vector<std::string> argv;
    /// The whole environment ("NAME=value"); empty: the caller's.
    std::vector<std::string> env;
    /// Standard output and error go to this file (created, truncated); "":
    /// /dev/null. Standard input is /dev/null.
    std::string output;
    /// A descriptor the child keeps open under the same number (e.g. the
    /// pipe end Xvfb writes its display number to); -1: none.
    int keep_fd = -1;
  };

  /// Starts the child. Throws UserError "cannot run ARGV0: <reason>" when
  /// the exec fails, SystemError when fork or the output file fails.
  explicit ChildProcess(const Spec& spec);
  ~ChildProcess();  ///< stop()
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  pid_t pid() const { return pid_; }
  /// The exit when the child has ended (then reaped, and the rest of its
  /// group killed), else nullopt. Does not block.
  std::optional<ChildExit> poll();
  /// Waits until the child ends, until deadline, or until *stop becomes
  /// non-zero (a StopSignals flag; may be null). nullopt when it is still
  /// running.
  std::optional<ChildExit> wait_until(std::chrono::steady_clock::time_point deadline,
                                      const volatile sig_atomic_t* stop);
  /// Stops the child's process group: SIGTERM, then SIGKILL when it has not
  /// ended within grace; reaps it. The exit it had (or was given). No-throw;
  /// a child already reaped returns its exit again.
  ChildExit stop(std::chrono::milliseconds grace = std::chrono::milliseconds(1000)) noexcept;
  /// The exit once known.
  const std::optional<ChildExit>& exit() const { return exit_; }

 private:
  pid_t pid_ = -1;
  std::optional<ChildExit> exit_;
};

/// While alive, SIGINT, SIGTERM and SIGHUP set flag() to the signal's number
/// instead of ending the process; the destructor puts the previous handlers
/// back. One instance at a time.
class StopSignals {
 public:
  StopSignals();
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;
  const volatile sig_atomic_t* flag() const;
  int caught() const;
  /// Puts the previous handlers back and raises the caught signal again
  /// (with ropsim's handlers: the pending outputs are removed, the process
  /// dies of the signal). Returns when no signal was caught.
  void reraise();

 private:
  struct sigaction old_[3];
  bool restored_ = false;
  void restore() noexcept;
};

/// A virtual X server (Xvfb) on a display it picks itself (-displayfd: the
/// first free one, no race with another server), with one screen of
/// width x height x 24 bits, no TCP listener. Stopped by the destructor.
class VirtualDisplay {
 public:
  /// xvfb: the Xvfb executable. log: where its output goes. Throws UserError
  /// when it does not come up within timeout (naming the last line it
  /// printed) or when *stop is raised meanwhile (the caller then reraises).
  VirtualDisplay(const std::string& xvfb, unsigned width, unsigned height, const std::string& log,
                 std::chrono::milliseconds timeout, const volatile sig_atomic_t* stop);
  /// ":N".
  const std::string& display() const { return display_; }
  /// The server's process, e.g. to check that it is still running.
  ChildProcess& process() { return *server_; }

 private:
  std::optional<ChildProcess> server_;
  std::string display_;
};

/// The last non-empty line of a text file (at most max_chars, from its
/// end), "" when there is none.
std::string last_line_of(const std::string& path, size_t max_chars = 200);

}  // namespace ropsim
