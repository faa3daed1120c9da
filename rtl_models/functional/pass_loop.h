// The passes of a method over its input (method.h passes_of), the one loop
// every fidelity runs them through: each pass begins on the functional ROP
// (or the golden model) first, and every pass after the first replays the
// input from its start.
#pragma once

namespace ropsim {

/// Runs body(pass, passes) for every pass of rop (passes(), begin_pass(i)),
/// after reopening the input (input = reopen()) for each pass after the first.
template <class Rop, class Input, class Reopen, class Body>
void for_each_pass(Rop& rop, Input& input, Reopen&& reopen, Body&& body) {
  const int passes = rop.passes();
  for (int pass = 0; pass < passes; ++pass) {
    rop.begin_pass(pass);
    if (pass > 0) input = reopen();
    body(pass, passes);
  }
}

/// The fraction of a run done: pass `pass` of `passes`, with the fraction
/// `consumed` of its input read.
inline double pass_progress(int pass, int passes, double consumed) {
  return (double(pass) + consumed) / double(passes);
}

}  // namespace ropsim
