#include "util/errors.h"

#include <cstdlib>
#include <cstring>
#include <new>
#include <system_error>

namespace ropsim {

std::string ErrorVerdict::message() const {
  return status == kUserErrorStatus ? "error: " + what : "internal error: " + what + ": please report it";
}

namespace {

std::string one_line(std::string s) {
  for (char& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  while (!s.empty() && s.back() == ' ') s.pop_back();
  return s;
}

/// The rule itself, on the dynamic type of what was thrown.
ErrorVerdict verdict_of(const std::exception& x) {
  if (dynamic_cast<const InternalError*>(&x)) return {kInternalErrorStatus, one_line(x.what())};
  if (dynamic_cast<const UserError*>(&x) || dynamic_cast<const std::system_error*>(&x))
    return {kUserErrorStatus, one_line(x.what())};
  if (dynamic_cast<const std::bad_alloc*>(&x)) return {kUserErrorStatus, "out of memory"};
  return {kInternalErrorStatus, one_line(x.what())};
}

}  // namespace

ErrorVerdict classify_error(const std::exception_ptr& e) {
  try {
    std::rethrow_exception(e);
  } catch (const std::exception& x) {
    return verdict_of(x);
  } catch (...) {
    return {kInternalErrorStatus, "an unknown exception"};
  }
}

int exit_status_of(const std::exception& e) { return verdict_of(e).status; }

void test_hook_internal_error(const char* place) {
  const char* t = std::getenv("ROPSIM_TEST_INTERNAL_ERROR");
  if (!t || !*t || std::strcmp(t, "0") == 0) return;
  bool elsewhere = false;  // a place other than main names the hook
  for (const char* p : {"study-point", "livepoint-worker", "livepoint-read"})
    elsewhere = elsewhere || !std::strcmp(t, p);
  if (std::strcmp(place, "main") == 0 ? !elsewhere : std::strcmp(t, place) == 0)
    throw InternalError(std::string("test hook ROPSIM_TEST_INTERNAL_ERROR=") + t + " is set");
}

}  // namespace ropsim
