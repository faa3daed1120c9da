// A FIFO queue in a ring buffer that grows by doubling: pushes at the back,
// pops from the front, and indexing from the front. Steady state allocates
// nothing, and an index is a mask, not std::deque's division by its block.
#pragma once
#include <cstddef>
#include <vector>

namespace ropsim {

template <class T>
class RingQueue {
 public:
  /// Room for `capacity` entries before the first growth (a power of two).
  explicit RingQueue(size_t capacity = 64) : v_(capacity), mask_(capacity - 1) {}
  bool empty() const { return n_ == 0; }
  size_t size() const { return n_; }
  T& front() { return v_[head_]; }
  const T& front() const { return v_[head_]; }
  /// Entry i from the front (0: the front).
  T& operator[](size_t i) { return v_[(head_ + i) & mask_]; }
  const T& operator[](size_t i) const { return v_[(head_ + i) & mask_]; }
  void push_back(const T& x) {
    if (n_ > mask_) grow();
    v_[(head_ + n_) & mask_] = x;
    ++n_;
  }
  void pop_front() {
    head_ = (head_ + 1) & mask_;
    --n_;
  }
  /// Calls f on every entry, front to back.
  template <class F>
  void for_each(F&& f) {
    for (size_t i = 0; i < n_; ++i) f((*this)[i]);
  }

 private:
  void grow() {
    std::vector<T> w(v_.size() * 2);
    for (size_t i = 0; i < n_; ++i) w[i] = v_[(head_ + i) & mask_];
    v_.swap(w);
    head_ = 0;
    mask_ = v_.size() - 1;
  }
  std::vector<T> v_;
  size_t mask_;  // the size is a power of two
  size_t head_ = 0, n_ = 0;
};

}  // namespace ropsim
