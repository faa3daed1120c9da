// A small open-addressing hash set of 64-bit keys (linear probing, backward-
// shift deletion, no tombstones): the pixel scoreboard inserts and erases one
// key per fragment, which std::unordered_set pays for with a heap node each.
#pragma once
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "rtl_models/algo/bits.h"

namespace ropsim {

class FlatSet {
 public:
  /// Holds up to max_size keys; the table is at most half full.
  explicit FlatSet(size_t max_size) {
    const size_t n = std::max<size_t>(16, next_pow2(2 * max_size));
    slots_.assign(n, kEmpty);
    mask_ = n - 1;
  }
  bool contains(uint64_t k) const {
    for (size_t i = index(k);; i = (i + 1) & mask_) {
      if (slots_[i] == k) return true;
      if (slots_[i] == kEmpty) return false;
    }
  }
  void insert(uint64_t k) {
    size_t i = index(k);
    while (slots_[i] != kEmpty) {
      if (slots_[i] == k) return;
      i = (i + 1) & mask_;
    }
    slots_[i] = k;
    ++size_;
  }
  void erase(uint64_t k) {
    size_t i = index(k);
    while (slots_[i] != k) {
      if (slots_[i] == kEmpty) return;
      i = (i + 1) & mask_;
    }
    // Backward shift: move later keys of the probe run into the hole.
    for (size_t j = (i + 1) & mask_; slots_[j] != kEmpty; j = (j + 1) & mask_) {
      const size_t home = index(slots_[j]);
      if (((j - home) & mask_) >= ((j - i) & mask_)) {
        slots_[i] = slots_[j];
        i = j;
      }
    }
    slots_[i] = kEmpty;
    --size_;
  }
  size_t size() const { return size_; }

 private:
  static constexpr uint64_t kEmpty = ~uint64_t{0};
  size_t index(uint64_t k) const { return size_t((k * 0x9E3779B97F4A7C15ull) >> 20) & mask_; }
  std::vector<uint64_t> slots_;
  size_t mask_ = 0, size_ = 0;
};

}  // namespace ropsim
