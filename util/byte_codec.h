// Little-endian byte encoding, the one way ropsim writes numbers into bytes:
// the trace file, the live-point library and the messages a worker process
// sends back. put_le/get_le move an n-byte unsigned field; ByteWriter and
// ByteReader append and read 8-byte words and length-prefixed strings.
#pragma once
#include <cstdint>
#include <cstring>
#include <string>

#include "util/errors.h"

namespace ropsim {

/// Writes the low n bytes of v at p, least significant first (n <= 8).
inline void put_le(uint8_t* p, uint64_t v, int n) {
  for (int i = 0; i < n; ++i) p[i] = uint8_t(v >> (8 * i));
}
/// Reads an n-byte little-endian unsigned field at p (n <= 8).
inline uint64_t get_le(const uint8_t* p, int n) {
  uint64_t v = 0;
  for (int i = 0; i < n; ++i) v |= uint64_t(p[i]) << (8 * i);
  return v;
}
/// A float as its IEEE-754 bits, little-endian (4 bytes).
inline void put_f32(uint8_t* p, float f) {
  uint32_t v;
  std::memcpy(&v, &f, 4);
  put_le(p, v, 4);
}
inline float get_f32(const uint8_t* p) {
  const uint32_t v = uint32_t(get_le(p, 4));
  float f;
  std::memcpy(&f, &v, 4);
  return f;
}

inline void put_u16(uint8_t* p, uint16_t v) { put_le(p, v, 2); }
inline void put_u32(uint8_t* p, uint32_t v) { put_le(p, v, 4); }
inline void put_u48(uint8_t* p, uint64_t v) { put_le(p, v, 6); }
inline void put_u64(uint8_t* p, uint64_t v) { put_le(p, v, 8); }
inline uint16_t get_u16(const uint8_t* p) { return uint16_t(get_le(p, 2)); }
inline uint32_t get_u32(const uint8_t* p) { return uint32_t(get_le(p, 4)); }
inline uint64_t get_u48(const uint8_t* p) { return get_le(p, 6); }
inline uint64_t get_u64(const uint8_t* p) { return get_le(p, 8); }

/// Appends 8-byte little-endian words and length-prefixed strings to a byte
/// string.
class ByteWriter {
 public:
  explicit ByteWriter(std::string& out) : out_(out) {}
  void u64(uint64_t v) {
    uint8_t b[8];
    put_le(b, v, 8);
    out_.append(reinterpret_cast<const char*>(b), 8);
  }
  /// Its length (u64), then its bytes.
  void str(const std::string& s) {
    u64(s.size());
    out_ += s;
  }

 private:
  std::string& out_;
};

/// Reads what a ByteWriter wrote. Reading past the end breaks the invariant
/// `what` names (the bytes come from ropsim itself, never from a user).
class ByteReader {
 public:
  ByteReader(const std::string& in, const char* what) : in_(in), what_(what) {}
  ByteReader(std::string&&, const char*) = delete;  // it keeps a reference
  uint64_t u64() {
    invariant(at_ + 8 <= in_.size(), what_);
    const uint64_t v = get_le(reinterpret_cast<const uint8_t*>(in_.data()) + at_, 8);
    at_ += 8;
    return v;
  }
  std::string str() {
    const uint64_t n = u64();
    invariant(n <= in_.size() - at_, what_);
    std::string s = in_.substr(at_, size_t(n));
    at_ += size_t(n);
    return s;
  }
  /// Whether every byte was read.
  bool done() const { return at_ == in_.size(); }

 private:
  const std::string& in_;
  const char* what_;
  size_t at_ = 0;
};

}  // namespace ropsim
