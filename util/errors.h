// The two kinds of error ropsim reports (README "Exit status"):
//  - UserError: the input or the environment is wrong (a bad trace, config,
//    scene, flag, or an output that cannot be written). One line naming the
//    file and record or key; exit status 1. The per-module error types
//    (TraceError, ImageError, ConfigError, SceneError, CaptureError) are user
//    errors too: they derive from std::runtime_error, as this does.
//    A SystemError is the environment's part of these: the system refused an
//    operation (ENOSPC, EIO, ...) and carries its errno, so that a caller
//    that can try again later (a study's rerun) tells it from a bad input.
//  - InternalError: an invariant of the simulator does not hold. It names the
//    invariant; exit status 2 ("please report it"). It derives from
//    std::logic_error, which the CLI maps to 2 as well.
// Bottom layer: no dependencies beyond the standard library.
#pragma once
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

}  // namespace ropsim
