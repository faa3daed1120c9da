// The two kinds of error ropsim reports (README "Exit status"), one hierarchy:
//  - UserError: the input or the environment is wrong (a bad trace, config,
//    scene, flag, or an output that cannot be written). One line naming the
//    file and record or key; exit status 1. Every module's error type derives
//    from it and keeps its name where it is thrown: TraceError, ConfigError,
//    SceneError, CaptureError, ImageError, ImageCodecError.
//    A SystemError is the environment's part of these: the system refused an
//    operation (ENOSPC, EIO, ...) and carries its errno, so that a caller
//    that can try again later (a study's rerun) tells it from a bad input.
//  - InternalError: an invariant of the simulator does not hold. It names the
//    invariant; exit status 2 ("please report it"). Thrown by invariant().
// Product code throws only these (and their subtypes). classify_error() is
// the one rule that maps whatever reached a top level -- main, a study's
// worker, a sampled run's live-point worker -- to its exit status and its
// one-line text, so an error in a worker reaches the user as it would from
// main.
// Bottom layer: no dependencies beyond the standard library.
#pragma once
#include <exception>
#include <stdexcept>
#include <string>

namespace ropsim {

class UserError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A UserError whose cause is the host (a full disk, an I/O error, no
/// memory...): the errno the system gave. Exit status 1, like every UserError.
class SystemError : public UserError {
 public:
  SystemError(const std::string& what, int err) : UserError(what), err_(err) {}
  int error_number() const { return err_; }

 private:
  int err_;
};

class InternalError : public std::logic_error {
 public:
  using std::logic_error::logic_error;
};

/// Throws InternalError("<what>") when cond is false. `what` names the
/// invariant ("retired tokens <= issued tokens"), not the symptom.
inline void invariant(bool cond, const char* what) {
  if (!cond) throw InternalError(what);
}

/// The exit status of a user error (a bad input, flag or file, or the host
/// refusing an operation) and of a broken invariant.
constexpr int kUserErrorStatus = 1;
constexpr int kInternalErrorStatus = 2;

/// What an error means to the user: its exit status and its text.
struct ErrorVerdict {
  int status = kInternalErrorStatus;
  std::string what;  ///< the error's own text, on one line
  /// The line ropsim prints after "ropsim: ": "error: <what>" (status 1) or
  /// "internal error: <what>: please report it" (status 2).
  std::string message() const;
};

/// The one rule. Status 1 (a user or environment error):
///   - UserError and every type derived from it (SystemError, TraceError, ...);
///   - std::system_error (std::filesystem::filesystem_error, a failed write):
///     the host refused an operation;
///   - std::bad_alloc, as "out of memory": the host ran out of memory, which
///     --memory-limit and the study's memory budget are there to avoid.
/// Status 2 (a broken invariant): InternalError, and anything else -- a
/// standard or library exception that escaped the code that should have
/// turned it into a UserError is a bug of the simulator too.
ErrorVerdict classify_error(const std::exception_ptr& e);
inline ErrorVerdict classify_current_exception() { return classify_error(std::current_exception()); }
/// classify_error(e).status.
int exit_status_of(const std::exception& e);

/// Test hook (docs/testing.md "Fault injection"): throws an InternalError
/// naming the hook when $ROPSIM_TEST_INTERNAL_ERROR names `place` -- "main"
/// (or any other non-empty value but 0: before a verb runs), "study-point"
/// (in a study point's task), "livepoint-worker" (in a sampled run's
/// worker process) or "livepoint-read" (reading a live-point library).
void test_hook_internal_error(const char* place);

}  // namespace ropsim
