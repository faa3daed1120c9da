// A short queue kept in ascending order: pushes land mostly at the back (so
// insertion shifts few entries), pops leave from the front. It is a RingQueue
// (ring_queue.h) with an ordered push, so steady state allocates nothing
// (std::deque allocated and freed a block every few hundred entries).
#pragma once
#include <cstddef>

#include "util/containers/ring_queue.h"

namespace ropsim {

template <class T, class Less>
class SortedRing {
 public:
  bool empty() const { return q_.empty(); }
  size_t size() const { return q_.size(); }
  const T& front() const { return q_[0]; }
  void pop_front() { q_.pop_front(); }
  /// Inserts x after every entry not greater than it (equal entries keep
  /// their push order).
  void push(const T& x) {
    q_.push_back(x);
    size_t i = q_.size() - 1;  // position from the front where x goes
    while (i > 0 && less_(x, q_[i - 1])) {
      q_[i] = q_[i - 1];
      --i;
    }
    q_[i] = x;
  }

 private:
  RingQueue<T> q_{16};
  Less less_{};
};

}  // namespace ropsim
