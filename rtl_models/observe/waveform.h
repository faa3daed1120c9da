// The waveform of a cycle run (--vcd FILE --vcd-window A:B): what every unit
// did, how full every FIFO was and what every DRAM channel's data bus moved,
// cycle by cycle, for the cycles A..B, written as a VCD with a clock: ten
// 100 ps time units per cycle (so GTKWave's ns are cycle numbers), the clock
// rising at 10c, where every signal of cycle c changes, and falling at
// 10c + 5; and a GTKWave save file that shows it (docs/reports.md
// "Waveforms").
//
// Like the IntervalLog, every source records an event under the cycle it
// happens at, never at the host's time: a unit's activity over the span of
// cycles it is charged (unit.h), a FIFO's pushes and pops at their cycles
// (timed_fifo.h), a DRAM burst over the cycles its data bus is busy. So a unit
// that runs decoupled, ahead of SystemC time, records the same waveform as in
// lockstep (Waveform.* tests: byte-identical files), and a --vcd run keeps its
// temporal decoupling: before and after the window, recording is one
// comparison per event. Each signal's events arrive in cycle order (a unit's
// charges, a FIFO's pushes, its pops and a channel's bursts each never go
// back in time), so a signal is a compact stream, and writing merges them.
//
// No SystemC here: the memory and core layers call it, the top declares the
// signals and writes the file.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "util/memory_budget.h"

namespace ropsim {

class Waveform {
 public:
  /// Records the cycles [first, last] (last >= first).
  Waveform(uint64_t first, uint64_t last);

  /// The current pass's first cycle in the run: the events that follow are
  /// of its cycles, counted from 0 (a multi-pass method's passes follow each
  /// other, as in the IntervalLog).
  void set_base(uint64_t cycle) { base_ = cycle; }

  // ---- declaration (before the run), in the order the file lists them;
  // a scope may be nested ("stochastic.rop0")
  /// A signal shown as a name from `states` (a VCD string variable: GTKWave
  /// shows the name); set() takes the index. Starts at states[0].
  int add_state(const std::string& scope, const std::string& name, std::vector<std::string> states);
  /// A non-negative count (a VCD integer, shown in decimal); set() takes it.
  int add_count(const std::string& scope, const std::string& name);
  /// A FIFO's occupancy (a VCD integer): entries pushed at or before the
  /// cycle and popped after it, from push() and pop().
  int add_occupancy(const std::string& scope, const std::string& name);

  // ---- recording (cycles of one signal never decrease, per stream)
  /// Signal `sig` has value v from cycle t on (the last set at a cycle wins);
  /// a set before the window gives the value the window starts with, one
  /// after it is ignored.
  void set(int sig, uint64_t t, uint64_t v) {
    t += base_;
    if (t <= last_) record(sig, t, v);
  }
  /// An entry enters (push) or leaves (pop) the FIFO of occupancy signal sig at cycle t.
  void push(int sig, uint64_t t) {
    t += base_;
    if (t <= last_) count_edge(sig, t, 0);
  }
  void pop(int sig, uint64_t t) {
    t += base_;
    if (t <= last_) count_edge(sig, t, 1);
  }

  // ---- output
  /// The file's text: `comment` in its header, `top` the outermost scope;
  /// the run's cycles are [0, end): the waveform stops at min(last, end - 1).
  /// Passes it to `out` in pieces of about 1 MiB.
  void write_vcd(const std::string& top, const std::string& comment, uint64_t end,
                 const std::function<void(std::string_view)>& out) const;
  /// A GTKWave save file (.gtkw) for that VCD at vcd_path (write_vcd's top
  /// and end): the clock and the cycle counter, then every scope's signals in
  /// the file's order under a comment line naming the scope (each ROP, the
  /// shared units, the DRAM), the scope tree expanded, the view starting at
  /// the window's first cycle and zoomed to show the whole window.
  std::string write_gtkw(const std::string& vcd_path, const std::string& top, uint64_t end) const;
  /// The last cycle the file shows (write_vcd's end), or first - 1 if none.
  uint64_t last_shown(uint64_t end) const;

  uint64_t first() const { return first_; }
  uint64_t last() const { return last_; }

  struct Signal {
    enum class Kind { kState, kCount, kOccupancy };
    Kind kind;
    std::string scope, name;
    std::vector<std::string> states;  ///< kState: the value names
    // One event stream (kState, kCount: (cycle delta, value) pairs) or two
    // (kOccupancy: pushes' and pops' cycle deltas), LEB128-coded.
    std::vector<uint8_t> stream[2];
    uint64_t last_t[2] = {0, 0};  ///< the latest cycle of each stream
    uint64_t before[2] = {0, 0};  ///< kOccupancy: pushes, pops before the window
    uint64_t initial = 0;         ///< kState, kCount: the value at the window's first cycle
  };
  const std::vector<Signal>& signals() const { return signals_; }

 private:
  std::vector<std::string> ordered_scopes() const;
  void record(int sig, uint64_t t, uint64_t v);
  void count_edge(int sig, uint64_t t, int which);
  void append(Signal& s, int which, uint64_t v);
  void check_order(Signal& s, int which, uint64_t t);
  uint64_t first_, last_, base_ = 0;
  std::vector<Signal> signals_;
  size_t bytes_ = 0;  // stream bytes, charged to the memory budget in steps
  BudgetShare mem_;
};

}  // namespace ropsim
