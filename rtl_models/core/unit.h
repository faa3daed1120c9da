// Base of every SystemC unit: one SC_METHOD woken by one event, never by a
// free-running clock; activity accounting without per-cycle work (the time
// between two activations is charged to the activity recorded at the first).
#pragma once
#include <systemc>

#include <algorithm>
#include <array>
#include <cstdint>
#include <string>

#include "clock.h"

namespace ropsim {

/// What a unit does in a cycle. Every cycle of the run is charged to one.
enum class Activity : int {
  kIdle,     ///< no work: before its first fragment or after its input closed
  kBusy,     ///< processing (a fragment's initiation interval)
  kStarved,  ///< waiting for input while upstream still works
  kBlocked,  ///< output FIFO full
  kHazard,   ///< pixel ordering: every waiting fragment's pixel is in flight, or the scoreboard is full
  kMemory,   ///< waiting for the ROP cache / DRAM
};
constexpr int kActivities = 6;
const char* to_string(Activity a);

struct UnitStats {
  std::array<uint64_t, kActivities> cycles{};  ///< cycles per Activity
  uint64_t fragments = 0;  ///< fragments accepted
  uint64_t samples = 0;    ///< samples processed (unit-specific: tested, sorted, hashed, written)
  uint64_t activations = 0;  ///< SC_METHOD activations (host cost)
};

class Unit : public sc_core::sc_module {
 public:
  SC_HAS_PROCESS(Unit);
  Unit(const sc_core::sc_module_name& name, const Clock& clk);

  /// Wakes the unit at the given cycle (now or later); the earliest request wins.
  void wake_at(uint64_t cycle) {
    if (cycle >= armed_) return;  // an earlier (or equal) wake is already pending
    armed_ = cycle;
    const uint64_t n = clk_.current();
    wake_.notify(cycle > n ? clk_.cycles(cycle - n) : sc_core::SC_ZERO_TIME);
  }
  /// Charges the cycles up to end to the current activity (end of the run).
  void close_accounting(uint64_t end) { set_activity(Activity::kIdle, end); }
  const UnitStats& stats() const { return stats_; }
  /// Unit-specific figures for the report: name, value, unit.
  struct Extra {
    std::string name;
    double value;
    std::string unit;
  };
  virtual std::vector<Extra> extras() const { return {}; }
  int trace_activity = 0;  ///< the Activity, for sc_trace inside --vcd-window

 protected:
  /// One activation at cycle now: move fragments, set the activity, and arm
  /// the next wake-up (or rely on a FIFO to wake the unit).
  virtual void step(uint64_t now) = 0;
  /// From cycle t the unit does a (inside a busy interval: after it).
  void set_activity(Activity a, uint64_t t) {
    charge_to(t);
    if (t < busy_end_) after_ = a;
    else act_ = a;
    if (clk_.tracing(t)) trace_activity = int(a);
  }
  /// Busy for [t, until), then `after` until the next change, so a unit need
  /// not wake at the end of its initiation interval just to account for it.
  void set_busy(uint64_t t, uint64_t until, Activity after) {
    charge_to(t);
    act_ = Activity::kBusy;
    busy_end_ = until;
    after_ = after;
    if (clk_.tracing(t)) trace_activity = int(Activity::kBusy);
  }
  const Clock& clk_;
  UnitStats stats_;

 private:
  void run();
  void charge_to(uint64_t t) {
    if (t <= since_) return;
    if (busy_end_ > since_) {
      const uint64_t e = std::min(busy_end_, t);
      stats_.cycles[size_t(Activity::kBusy)] += e - since_;
      since_ = e;
      if (since_ == busy_end_) act_ = after_;
    }
    if (t > since_) {
      stats_.cycles[size_t(act_)] += t - since_;
      since_ = t;
    }
  }
  sc_core::sc_event wake_;
  uint64_t armed_ = ~uint64_t{0};
  Activity act_ = Activity::kIdle, after_ = Activity::kIdle;
  uint64_t since_ = 0, busy_end_ = 0;
};

}  // namespace ropsim
