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

#include "rtl_models/algo/bits.h"
#include "rtl_models/core/unit.h"

namespace ropsim {

struct FifoStats {
  std::string name;
  uint32_t capacity = 0;
  uint64_t pushes = 0;
  uint32_t max_occupancy = 0;
  double mean_occupancy = 0;  ///< entries, time-averaged over the run
  uint64_t full_cycles = 0;   ///< cycles at capacity
};

/// Occupancy over simulated time from push and pop cycles that arrive in
/// host order: each side's cycles never decrease, but one side may run ahead
/// of the other (a decoupled unit). Occupancy at cycle t counts the entries
/// pushed at or before t and popped after t. Entries leave in order, so every
/// figure is a fact about a few entries at most `capacity` apart, kept in two
/// small rings:
///  - entry-cycles: the sum of (pop - push) over the entries;
///  - cycles at capacity: entry j completes a full FIFO from its push until
///    entry j - capacity + 1 leaves, counted when the later of the two arrives;
///  - the maximum: the occupancy after entry j's push is j + 1 - (entries
///    popped by then), final at the first pop after that cycle.
class OccupancyStats {
 public:
  explicit OccupancyStats(uint32_t capacity) : cap_(capacity) {
    const size_t n = next_pow2(size_t{capacity});  // index by mask
    push_t_.resize(n);
    pop_t_.resize(n);
    mask_ = n - 1;
  }
  void push(uint64_t t) {
    const uint64_t j = pushes_;
    push_t_[j & mask_] = t;
    if (j + 1 >= cap_ && j + 1 - cap_ < pops_) {  // entry j - cap + 1 has left: full until then
      const uint64_t p = pop_t_[(j + 1 - cap_) & mask_];
      if (p > t) full_ += p - t;
    }
    // A consumer ahead in time has already popped, after t, some entries that
    // were still in at t: the first of them gives the occupancy after this push.
    if (pend_ == j && pops_ && pop_t_[(pops_ - 1) & mask_] > t) {
      uint64_t k = pops_;
      while (k > 0 && k + cap_ > j + 1 && pop_t_[(k - 1) & mask_] > t) --k;
      max_ = std::max(max_, j + 1 - k);
      ++pend_;
    }
    ++pushes_;
  }
  void pop(uint64_t t) {
    const uint64_t i = pops_;
    area_ += t - push_t_[i & mask_];
    // Pushes before t now know how many entries had left by their cycle: i.
    for (; pend_ < pushes_ && push_t_[pend_ & mask_] < t; ++pend_) max_ = std::max(max_, pend_ + 1 - i);
    if (i + cap_ - 1 < pushes_) {  // entry i + cap - 1 was pushed: the FIFO was full from then until now
      const uint64_t q = push_t_[(i + cap_ - 1) & mask_];
      if (t > q) full_ += t - q;
    }
    pop_t_[i & mask_] = t;
    ++pops_;
  }
  /// Time-averaged entries, cycles at capacity and the maximum over [0, end).
  void finish(uint64_t end, double& mean, uint64_t& full, uint32_t& max) const {
    uint64_t area = area_, f = full_, m = max_;
    for (uint64_t i = pops_; i < pushes_; ++i) {  // still in at the end
      area += end - push_t_[i & mask_];
      if (i + cap_ - 1 < pushes_ && end > push_t_[(i + cap_ - 1) & mask_]) f += end - push_t_[(i + cap_ - 1) & mask_];
    }
    for (uint64_t j = pend_; j < pushes_; ++j) m = std::max(m, j + 1 - pops_);
    mean = end ? double(area) / double(end) : 0.0;
    full = f;
    max = uint32_t(m);
  }

 private:
  uint64_t cap_;
  std::vector<uint64_t> push_t_, pop_t_;  // by entry index mod a power of two >= capacity
  uint64_t mask_ = 0;
  uint64_t pushes_ = 0, pops_ = 0, pend_ = 0;
  uint64_t area_ = 0, full_ = 0, max_ = 0;
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
    if (wave_) wave_->push(wave_sig_, t);
    consumer_->on_input(visible);
  }
  /// The producer found no slot at cycle t: it hears (on_space) the cycle a
  /// slot frees, now if that is decided, else when the consumer pops.
  void wait_for_space(uint64_t t) {
    const uint64_t s = space_from();
    if (s != kUndecided)
      producer_->on_space(std::max(s, t + 1));
    else
      producer_waiting_ = true;
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
    if (wave_) wave_->pop(wave_sig_, t);
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
  /// Also records every push and pop in `wave`'s occupancy signal `sig`
  /// (--vcd); before the run.
  void trace_to(Waveform* wave, int sig) {
    wave_ = wave;
    wave_sig_ = sig;
  }
  /// The unit that reads the FIFO (connect).
  Unit* consumer() const { return consumer_; }
  /// The host bytes a FIFO of `capacity` entries allocates: its ring and its
  /// occupancy statistics' push and pop times (memory_estimate.h).
  static uint64_t bytes_for(uint32_t capacity) {
    return uint64_t(capacity) * sizeof(Entry) + 2 * uint64_t(next_pow2(size_t{capacity})) * sizeof(uint64_t);
  }

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
  Waveform* wave_ = nullptr;
  int wave_sig_ = -1;
};

}  // namespace ropsim
