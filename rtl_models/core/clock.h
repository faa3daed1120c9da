// The ROP clock: converts cycles (the config's unit) to sc_time once. All
// units of one pipeline share one Clock.
#pragma once
#include <cmath>
#include <cstdint>
#include <systemc>

namespace ropsim {

class Scheduler;

class Clock {
 public:
  /// Call after the simulation context exists (sc_time needs its resolution).
  explicit Clock(double frequency_ghz)
      : ghz_(frequency_ghz),
        ticks_(sc_core::sc_time(double(std::max<long long>(1, std::llround(1000.0 / frequency_ghz))), sc_core::SC_PS)
                   .value()) {}
  /// The current cycle.
  uint64_t now() const { return sc_core::sc_time_stamp().value() / ticks_; }
  /// The process that runs the units of this clock (scheduler.h).
  void attach(Scheduler* s) { sched_ = s; }
  Scheduler* scheduler() const { return sched_; }
  /// The current cycle as of the running unit activation (set by Unit::run,
  /// so the division in now() runs once per activation, not per wake-up).
  uint64_t current() const { return current_; }
  void set_current(uint64_t cycle) const { current_ = cycle; }
  /// A delay of n cycles.
  sc_core::sc_time cycles(uint64_t n) const { return sc_core::sc_time::from_value(n * ticks_); }
  double frequency_ghz() const { return ghz_; }
  /// The period actually simulated, in picoseconds (1000 / GHz, rounded).
  uint64_t period_ps() const { return ticks_ / sc_core::sc_time(1, sc_core::SC_PS).value(); }

 private:
  double ghz_;
  uint64_t ticks_;
  mutable uint64_t current_ = 0;
  Scheduler* sched_ = nullptr;
};

}  // namespace ropsim
