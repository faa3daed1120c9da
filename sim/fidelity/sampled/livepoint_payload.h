// The live-point library's payload (docs/livepoints.md "The file"): every
// field little-endian, in the order encode_livepoint_payload writes it, and
// every read bounds-checked by decode_livepoint_payload. livepoint_file.cpp
// frames, hashes and compresses it.
#pragma once
#include <cstdint>
#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include "sim/fidelity/sampled/livepoint_file.h"
#include "util/byte_codec.h"

namespace ropsim {

/// Any count a library holds is below this; one read beyond it is corrupt.
constexpr uint64_t kMaxLivePointCount = uint64_t{1} << 40;

/// The payload, little-endian, field by field (util/byte_codec.h; arrays
/// as this little-endian host holds them).
class PayloadWriter {
 public:
  PayloadWriter() = default;
  /// With a drain, piece() hands the bytes gathered so far to it once there
  /// are kPiece of them, and flush() hands over the rest (a file written as
  /// it is encoded); without, the bytes stay in bytes().
  explicit PayloadWriter(std::function<void(const uint8_t*, size_t)> drain) : drain_(std::move(drain)) {}
  static constexpr size_t kPiece = size_t(1) << 20;
  void piece() {
    if (drain_ && b_.size() >= kPiece) flush();
  }
  void flush() {
    if (!drain_ || b_.empty()) return;
    drain_(b_.data(), b_.size());
    b_.clear();
  }
  void u8(uint8_t v) { b_.push_back(v); }
  void u16(uint16_t v) { raw(v, 2); }
  void u32(uint32_t v) { raw(v, 4); }
  void u64(uint64_t v) { raw(v, 8); }
  void f32(float v) {
    uint8_t p[4];
    put_f32(p, v);
    b_.insert(b_.end(), p, p + 4);
  }
  void str(const std::string& s) {
    u64(s.size());
    b_.insert(b_.end(), s.begin(), s.end());
  }
  /// n values of T, each little-endian (this host's order: see the static_assert).
  template <class T>
  void array(const T* v, size_t n) {
    const auto* p = reinterpret_cast<const uint8_t*>(v);
    b_.insert(b_.end(), p, p + n * sizeof(T));
  }
  std::vector<uint8_t>& bytes() { return b_; }

 private:
  void raw(uint64_t v, int n) {
    uint8_t p[8];
    put_le(p, v, n);
    b_.insert(b_.end(), p, p + n);
  }
  std::vector<uint8_t> b_;
  std::function<void(const uint8_t*, size_t)> drain_;
};

/// The library's payload into p (in pieces, when p drains).
void encode_livepoint_payload(const LivePoints& lib, PayloadWriter& p);
/// The library a payload holds, its points charged to the memory budget as
/// they are decoded. Throws UserError naming `path` and what was being read.
LivePoints decode_livepoint_payload(const std::vector<uint8_t>& bytes, const std::string& path);

}  // namespace ropsim
