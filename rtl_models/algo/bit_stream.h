// LSB-first bit streams: the encoded compressed tiles (compression.h).
#pragma once
#include <cstdint>
#include <vector>

namespace ropsim {

/// LSB-first bit stream (the encoded tiles).
class BitWriter {
 public:
  void put(uint64_t v, int n) {
    for (int i = 0; i < n; ++i, ++bit_) {
      if ((bit_ & 7) == 0) bytes_.push_back(0);
      bytes_.back() |= uint8_t((v >> i & 1u) << (bit_ & 7));
    }
  }
  uint64_t bits() const { return bit_; }
  const std::vector<uint8_t>& bytes() const { return bytes_; }

 private:
  std::vector<uint8_t> bytes_;
  uint64_t bit_ = 0;
};

class BitReader {
 public:
  explicit BitReader(const std::vector<uint8_t>& b) : b_(b) {}
  uint64_t get(int n) {
    uint64_t v = 0;
    for (int i = 0; i < n; ++i, ++bit_)
      if (bit_ >> 3 < b_.size()) v |= uint64_t(b_[bit_ >> 3] >> (bit_ & 7) & 1u) << i;
    return v;
  }

 private:
  const std::vector<uint8_t>& b_;
  uint64_t bit_ = 0;
};

}  // namespace ropsim
