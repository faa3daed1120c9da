// The process that runs the units. SystemC sees one SC_METHOD and one event
// per pipeline: each activation runs, in a fixed order (the order the units
// were built: source, distributor, then ROP by ROP from ordering to
// writeback), every unit that asked to wake at the current cycle, again and
// again while one asks for the current cycle (like SystemC's delta cycles),
// and notifies the event for the earliest cycle any unit asked for next.
//
// Why not one SC_METHOD per unit: SystemC runs the processes of one time step
// in an order it does not specify, and that order reaches the results where
// two units meet a shared resource in one cycle (two ROPs' depth tests on one
// DRAM channel). A fixed order makes every result independent of the kernel's
// process order (lockstep and decoupled runs, and any SystemC build, give the
// same cycles), and several units due in one cycle cost one kernel activation
// instead of one each. Idle cycles still cost nothing: no unit asks for them.
#pragma once
#include <cstdint>
#include <systemc>
#include <utility>
#include <vector>

#include "rtl_models/core/clock.h"

namespace ropsim {

class Unit;

class Scheduler : public sc_core::sc_module {
 public:
  SC_HAS_PROCESS(Scheduler);
  /// Attaches itself to the clock; the units built on that clock register here.
  Scheduler(const sc_core::sc_module_name& name, Clock& clk);
  /// Registers a unit; returns its place in the run order.
  uint32_t add(Unit* u);
  /// Unit `index` runs at `cycle` (the current cycle or later).
  void request(uint32_t index, uint64_t cycle);
  /// SystemC process activations so far (the host cost of the kernel).
  uint64_t activations() const { return activations_; }

 private:
  void run();
  void notify(uint64_t cycle);
  void mark_due(uint32_t index) { due_[index >> 6] |= uint64_t{1} << (index & 63); }
  Clock& clk_;
  sc_core::sc_event wake_;
  std::vector<Unit*> units_;
  std::vector<std::vector<uint64_t>> wakes_;  // per unit: requested cycles, descending, distinct
  std::vector<uint64_t> due_;                 // bit per unit: runs in the current cycle
  std::vector<uint64_t> earliest_;            // per unit: wakes_.back(), ~0 if none
  std::vector<uint32_t> waiting_;             // the units with a request (decoupled units rarely have one)
  uint64_t armed_ = ~uint64_t{0};             // cycle of the pending notification (~0: none)
  uint64_t next_ = ~uint64_t{0};              // while running: the earliest request after now
  bool running_ = false, again_ = false;
  uint32_t at_ = 0;  // the unit running now
  uint64_t activations_ = 0;
};

}  // namespace ropsim
