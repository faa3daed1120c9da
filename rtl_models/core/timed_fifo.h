// A bounded FIFO between two units. An entry pushed at cycle t becomes visible
// to the consumer at its "visible" cycle (> t: the producer's latency), so a
// pipelined producer needs one activation per fragment, not one per stage.
// A slot freed at cycle t is usable by the producer from t + 1, so the result
// never depends on the order in which SystemC runs two units in one cycle.
// Capacity = the configured depth + the producer's pipeline registers.
//
// Every entry keeps the cycles it was pushed, became visible and was popped,
// so a decoupled unit (unit.h) may push or pop ahead of SystemC time and the
// other side still sees the FIFO exactly as it is at its own cycle: a push at
// cycle t needs the entry `capacity` pushes back to have left before t, which
// is a fact about that entry, not about when the host ran the pop.
#pragma once
#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "unit.h"

namespace ropsim {

struct FifoStats {
  std::string name;
  uint32_t capacity = 0;
  uint64_t pushes = 0;
  uint32_t max_occupancy = 0;
  double mean_occupancy = 0;   ///< entries, time-averaged over the run
  uint64_t full_cycles = 0;    ///< cycles at capacity
};

/// Occupancy over simulated time from push and pop cycles that arrive in
/// host order: each side's cycles never decrease, but one side may run ahead
/// of the other. Events older than both sides' latest cycle are final and are
/// folded into the statistics; the rest wait (at most about two capacities).
class OccupancyStats {
 public:
  explicit OccupancyStats(uint32_t capacity) : cap_(capacity) {}
  void push(uint64_t t) {
    pushes_.push_back(t);
    last_push_ = t;
    fold(std::min(last_push_, last_pop_));
  }
  void pop(uint64_t t) {
    pops_.push_back(t);
    last_pop_ = t;
    fold(std::min(last_push_, last_pop_));
  }
  /// Entry-cycles, cycles at capacity and the maximum over [0, end).
  void finish(uint64_t end, double& mean, uint64_t& full, uint32_t& max) {
    fold(~uint64_t{0});
    const uint64_t span = end > since_ ? end - since_ : 0;
    mean = end ? double(area_ + uint64_t(occ_) * span) / double(end) : 0.0;
    full = full_ + (occ_ == cap_ ? span : 0);
    max = max_;
  }

 private:
  /// A queue of cycles (a ring that grows; no allocation in steady state).
  class Times {
   public:
    bool empty() const { return n_ == 0; }
    uint64_t front() const { return v_[head_]; }
    void pop_front() {
      head_ = (head_ + 1) & (v_.size() - 1);
      --n_;
    }
    void push_back(uint64_t t) {
      if (n_ == v_.size()) grow();
      v_[(head_ + n_) & (v_.size() - 1)] = t;
      ++n_;
    }

   private:
    void grow() {
      std::vector<uint64_t> w(v_.size() * 2);
      for (size_t i = 0; i < n_; ++i) w[i] = v_[(head_ + i) & (v_.size() - 1)];
      v_.swap(w);
      head_ = 0;
    }
    std::vector<uint64_t> v_ = std::vector<uint64_t>(16);
    size_t head_ = 0, n_ = 0;
  };
  /// Folds every event before cycle h (no later event can precede h).
  void fold(uint64_t h) {
    for (;;) {
      const uint64_t tp = pushes_.empty() ? ~uint64_t{0} : pushes_.front();
      const uint64_t to = pops_.empty() ? ~uint64_t{0} : pops_.front();
      const uint64_t t = std::min(tp, to);
      if (t >= h || t == ~uint64_t{0}) return;
      area_ += uint64_t(occ_) * (t - since_);
      if (occ_ == cap_) full_ += t - since_;
      since_ = t;
      while (!pushes_.empty() && pushes_.front() == t) {
        ++occ_;
        pushes_.pop_front();
      }
      while (!pops_.empty() && pops_.front() == t) {
        --occ_;
        pops_.pop_front();
      }
      max_ = std::max(max_, occ_);
    }
  }
  uint32_t cap_;
  Times pushes_, pops_;
  uint64_t last_push_ = 0, last_pop_ = 0;
  uint32_t occ_ = 0, max_ = 0;
  uint64_t since_ = 0, area_ = 0, full_ = 0;
};

template <class T>
class TimedFifo {
 public:
  static constexpr uint64_t kUndecided = ~uint64_t{0};

  TimedFifo(std::string name, uint32_t capacity, const Clock& clk)
      : name_(std::move(name)), cap_(capacity), clk_(clk), ring_(capacity), occ_(capacity) {}

  void connect(Unit* producer, Unit* consumer) {
    producer_ = producer;
    consumer_ = consumer;
  }
  const std::string& name() const { return name_; }
  uint32_t capacity() const { return cap_; }
  /// Entries pushed and not yet popped, whatever their cycles.
  uint32_t size() const { return size_; }
  bool empty() const { return size_ == 0; }

  // ---- producer side
  /// A push at cycle t has a slot: the entry `capacity` pushes back has left
  /// before t.
  bool can_push(uint64_t t) const { return size_ < cap_ && (pushes_ < cap_ || ring_[tail_].popped < t); }
  /// The first cycle a push has a slot, or kUndecided while the entry whose
  /// slot it is has not been popped yet.
  uint64_t space_from() const {
    if (size_ == cap_) return kUndecided;
    return pushes_ < cap_ ? 0 : ring_[tail_].popped + 1;
  }
  /// Pushes v at cycle t; the consumer sees it at max(visible, t + 1) and
  /// never before an earlier entry (in order).
  void push(T v, uint64_t t, uint64_t visible) {
    visible = std::max({visible, t + 1, last_visible_});
    last_visible_ = visible;
    ring_[tail_] = Entry{v, t, visible, 0};
    tail_ = tail_ + 1 == cap_ ? 0 : tail_ + 1;
    ++size_;
    ++pushes_;
    occ_.push(t);
    if (clk_.tracing(t)) trace_occupancy = int(size_);
    consumer_->on_input(visible);
  }
  /// The producer found no slot at cycle t: it hears (on_space) the cycle a
  /// slot frees, now if that is decided, else when the consumer pops.
  void wait_for_space(uint64_t t) {
    const uint64_t s = space_from();
    if (s != kUndecided) producer_->on_space(std::max(s, t + 1));
    else producer_waiting_ = true;
  }
  /// A decoupled producer that cannot tell yet whether a slot is free at its
  /// cycle (space_from() is kUndecided) hears (on_space) at the next pop.
  void notify_on_pop() { producer_waiting_ = true; }
  /// The producer will push nothing more that is visible at or before cycle
  /// `cycle` (a decoupled producer says so after each of its clocks).
  void settle(uint64_t cycle) {
    if (cycle <= settled_) return;
    settled_ = cycle;
    consumer_->on_settle();
  }
  /// The producer will push nothing after cycle t; the consumer hears it
  /// (on_close) from t + 1.
  void close(uint64_t t) {
    closed_ = true;
    closed_at_ = t;
    consumer_->on_close(t + 1);
  }
  /// The producer has closed the FIFO (whatever the cycle).
  bool closed() const { return closed_; }

  // ---- consumer side
  /// The head entry is visible at cycle t.
  bool can_pop(uint64_t t) const { return size_ && ring_[head_].visible <= t; }
  uint64_t head_visible() const { return ring_[head_].visible; }
  const T& front() const { return ring_[head_].value; }
  T pop(uint64_t t) {
    Entry& e = ring_[head_];
    e.popped = t;
    T v = e.value;  // on_space below may let a decoupled producer refill this very slot
    head_ = head_ + 1 == cap_ ? 0 : head_ + 1;
    --size_;
    occ_.pop(t);
    if (clk_.tracing(t)) trace_occupancy = int(size_);
    if (producer_waiting_) {
      producer_waiting_ = false;
      producer_->on_space(t + 1);
    }
    return v;
  }
  /// Every entry visible at or before this cycle has been pushed: a consumer
  /// that takes several entries in one clock may decide that clock. A full
  /// FIFO gets its next entry only after the consumer's next pop, so all that
  /// clock's entries are in then.
  uint64_t settled() const { return closed_ || size_ == cap_ ? kUndecided : settled_; }
  /// At cycle t the FIFO holds an entry, visible or not (an entry pushed at
  /// cycle c is seen from c + 1, as a close is: never by SystemC run order).
  bool occupied(uint64_t t) const { return size_ && ring_[head_].pushed < t; }
  /// Closed, as seen at cycle t: a close at cycle c is seen from c + 1.
  bool closed_by(uint64_t t) const { return closed_ && closed_at_ < t; }

  FifoStats stats(uint64_t end) {
    FifoStats s;
    s.name = name_;
    s.capacity = cap_;
    s.pushes = pushes_;
    occ_.finish(end, s.mean_occupancy, s.full_cycles, s.max_occupancy);
    return s;
  }
  int trace_occupancy = 0;  ///< for sc_trace inside --vcd-window (lockstep runs)

 private:
  struct Entry {
    T value{};
    uint64_t pushed = 0, visible = 0, popped = 0;
  };
  std::string name_;
  uint32_t cap_;
  const Clock& clk_;
  std::vector<Entry> ring_;  // entry i lives in slot i mod capacity
  uint32_t head_ = 0, tail_ = 0, size_ = 0;
  uint64_t pushes_ = 0, last_visible_ = 0, closed_at_ = 0, settled_ = 0;
  bool producer_waiting_ = false, closed_ = false;
  Unit* producer_ = nullptr;
  Unit* consumer_ = nullptr;
  OccupancyStats occ_;
};

}  // namespace ropsim
