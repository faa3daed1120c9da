// A short queue kept in ascending order: pushes land mostly at the back (so
// insertion shifts few entries), pops leave from the front. A ring buffer
// that grows by doubling, so steady state allocates nothing (std::deque
// allocated and freed a block every few hundred entries).
#pragma once
#include <cstddef>
#include <vector>

namespace ropsim {

template <class T, class Less>
class SortedRing {
 public:
  bool empty() const { return n_ == 0; }
  size_t size() const { return n_; }
  const T& front() const { return v_[head_]; }
  void pop_front() {
    head_ = (head_ + 1) & (v_.size() - 1);
    --n_;
  }
  void push(const T& x) {
    if (n_ == v_.size()) grow();
    const size_t mask = v_.size() - 1;
    size_t i = n_;  // position from the head where x goes
    while (i > 0 && less_(x, v_[(head_ + i - 1) & mask])) {
      v_[(head_ + i) & mask] = v_[(head_ + i - 1) & mask];
      --i;
    }
    v_[(head_ + i) & mask] = x;
    ++n_;
  }

 private:
  void grow() {
    std::vector<T> w(v_.size() * 2);
    for (size_t i = 0; i < n_; ++i) w[i] = v_[(head_ + i) & (v_.size() - 1)];
    v_.swap(w);
    head_ = 0;
  }
  std::vector<T> v_ = std::vector<T>(16);
  size_t head_ = 0, n_ = 0;
  Less less_{};
};

}  // namespace ropsim
