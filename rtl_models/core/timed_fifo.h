// A bounded FIFO between two units. An entry pushed at cycle t becomes visible
// to the consumer at its "visible" cycle (> t: the producer's latency), so a
// pipelined producer needs one activation per fragment, not one per stage.
// A slot freed at cycle t is usable by the producer from t + 1, so the result
// never depends on the order in which SystemC runs two units in one cycle.
// Capacity = the configured depth + the producer's pipeline registers.
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

template <class T>
class TimedFifo {
 public:
  TimedFifo(std::string name, uint32_t capacity, const Clock& clk)
      : name_(std::move(name)), cap_(capacity), clk_(clk), ring_(capacity) {}

  void connect(Unit* producer, Unit* consumer) {
    producer_ = producer;
    consumer_ = consumer;
  }
  const std::string& name() const { return name_; }
  uint32_t capacity() const { return cap_; }
  uint32_t size() const { return size_; }
  bool empty() const { return size_ == 0; }

  bool can_push(uint64_t now) const { return size_ + (last_pop_ == now ? pops_now_ : 0) < cap_; }
  /// Pushes v at cycle now; the consumer sees it at max(visible, now + 1) and
  /// never before an earlier entry (in-order).
  void push(T v, uint64_t now, uint64_t visible) {
    visible = std::max({visible, now + 1, last_visible_});
    last_visible_ = visible;
    account(now);
    ring_[(head_ + size_) % cap_] = Entry{v, visible};
    ++size_;
    ++pushes_;
    if (size_ > max_) max_ = size_;
    if (clk_.tracing(now)) trace_occupancy = int(size_);
    consumer_->wake_at(visible);
  }
  /// The head entry is visible at cycle now.
  bool can_pop(uint64_t now) const { return size_ && ring_[head_].visible <= now; }
  uint64_t head_visible() const { return ring_[head_].visible; }
  const T& front() const { return ring_[head_].value; }
  T pop(uint64_t now) {
    account(now);
    T v = ring_[head_].value;
    head_ = (head_ + 1) % cap_;
    --size_;
    if (last_pop_ != now) {
      last_pop_ = now;
      pops_now_ = 0;
    }
    ++pops_now_;
    if (clk_.tracing(now)) trace_occupancy = int(size_);
    if (producer_waiting_) {
      producer_waiting_ = false;
      producer_->wake_at(now + 1);
    }
    return v;
  }
  /// The producer found the FIFO full at cycle now: wake it when a slot
  /// frees (at now + 1 if one was freed this very cycle).
  void wait_for_space(uint64_t now) {
    if (size_ < cap_) producer_->wake_at(now + 1);
    else producer_waiting_ = true;
  }
  /// The producer will push nothing more; the consumer is woken to notice.
  void close(uint64_t now) {
    closed_ = true;
    consumer_->wake_at(now + 1);
  }
  bool closed() const { return closed_; }
  /// Closed and empty: the consumer has seen everything.
  bool drained() const { return closed_ && size_ == 0; }

  FifoStats stats(uint64_t end) {
    account(end);
    FifoStats s;
    s.name = name_;
    s.capacity = cap_;
    s.pushes = pushes_;
    s.max_occupancy = max_;
    s.mean_occupancy = end ? double(area_) / double(end) : 0.0;
    s.full_cycles = full_;
    return s;
  }
  int trace_occupancy = 0;  ///< for sc_trace inside --vcd-window

 private:
  struct Entry {
    T value{};
    uint64_t visible = 0;
  };
  void account(uint64_t now) {
    if (now > since_) {
      area_ += uint64_t(size_) * (now - since_);
      if (size_ == cap_) full_ += now - since_;
      since_ = now;
    }
  }
  std::string name_;
  uint32_t cap_;
  const Clock& clk_;
  std::vector<Entry> ring_;
  uint32_t head_ = 0, size_ = 0, max_ = 0;
  uint64_t last_visible_ = 0, last_pop_ = ~uint64_t{0};
  uint32_t pops_now_ = 0;
  bool producer_waiting_ = false, closed_ = false;
  Unit* producer_ = nullptr;
  Unit* consumer_ = nullptr;
  uint64_t pushes_ = 0, area_ = 0, full_ = 0, since_ = 0;
};

}  // namespace ropsim
