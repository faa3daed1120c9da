#include "rtl_models/core/scheduler.h"

#include <algorithm>

#include "rtl_models/algo/bits.h"
#include "rtl_models/core/unit.h"

namespace ropsim {

Scheduler::Scheduler(const sc_core::sc_module_name& name, Clock& clk) : sc_module(name), clk_(clk) {
  SC_METHOD(run);
  sensitive << wake_;
  dont_initialize();
  clk.attach(this);
}

uint32_t Scheduler::add(Unit* u) {
  units_.push_back(u);
  wakes_.emplace_back();
  earliest_.push_back(~uint64_t{0});
  due_.resize(ceil_div(units_.size(), size_t{64}));
  return uint32_t(units_.size() - 1);
}

void Scheduler::request(uint32_t index, uint64_t cycle) {
  if (running_ && cycle == clk_.current()) {
    // This cycle: later in this pass if the unit comes later, else another pass.
    mark_due(index);
    if (index <= at_) again_ = true;
    return;
  }
  if (cycle == earliest_[index]) return;  // the common repeat
  std::vector<uint64_t>& w = wakes_[index];
  // Descending, so the earliest is at the back and leaves without a shift.
  const auto it = std::lower_bound(w.begin(), w.end(), cycle, std::greater<uint64_t>());
  if (it != w.end() && *it == cycle) return;
  const bool earliest = it == w.end();
  if (w.empty()) waiting_.push_back(index);
  w.insert(it, cycle);
  if (!earliest) return;
  earliest_[index] = cycle;
  if (running_)
    next_ = std::min(next_, cycle);
  else if (cycle < armed_)
    notify(cycle);
}

void Scheduler::notify(uint64_t cycle) {
  armed_ = cycle;
  const uint64_t n = clk_.current();
  wake_.notify(cycle > n ? clk_.cycles(cycle - n) : sc_core::SC_ZERO_TIME);
}

void Scheduler::run() {
  ++activations_;
  // The cycle this activation was notified for (the only notifications of
  // wake_ are notify()'s): no division of sc_time_stamp() per activation.
  const uint64_t now = armed_;
  clk_.set_current(now);
  armed_ = ~uint64_t{0};
  next_ = ~uint64_t{0};  // the earliest request after now, kept up to date by request()
  for (size_t k = 0; k < waiting_.size();) {
    const uint32_t i = waiting_[k];
    if (earliest_[i] <= now) {
      std::vector<uint64_t>& w = wakes_[i];
      w.pop_back();  // requests are never for a past cycle: the earliest is now
      earliest_[i] = w.empty() ? ~uint64_t{0} : w.back();
      mark_due(i);
    }
    if (earliest_[i] == ~uint64_t{0}) {
      waiting_[k] = waiting_.back();
      waiting_.pop_back();
    } else {
      next_ = std::min(next_, earliest_[i]);
      ++k;
    }
  }
  running_ = true;
  do {
    again_ = false;
    for (size_t k = 0; k < due_.size(); ++k)
      while (due_[k]) {
        at_ = uint32_t(k * 64 + size_t(__builtin_ctzll(due_[k])));
        due_[k] &= due_[k] - 1;
        units_[at_]->activate(now);
      }
  } while (again_);
  running_ = false;
  if (next_ != ~uint64_t{0}) notify(next_);
}

}  // namespace ropsim
