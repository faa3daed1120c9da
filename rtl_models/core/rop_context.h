// What the units of one pipeline share: the trace header, the method and its
// numerics, the functional per-sample state (the same SampleStore as the
// golden model), the event counters, the fragment tokens, and the memory map.
#pragma once
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "address_map.h"
#include "conversion_memo.h"
#include "golden_model.h"
#include "sample_store.h"
#include "trace.h"
#include "tracker.h"

namespace ropsim {

/// A fragment in flight, with what the units have computed for it so far.
struct FragToken {
  Fragment f;
  uint64_t seq = 0;        ///< position in the trace (API order)
  uint32_t rop = 0;        ///< the ROP unit that owns its pixel
  uint64_t pixel_key = 0;  ///< y * width + x
  PixelRef px{};           ///< the pixel's functional state (set by the trace source)
  uint64_t covered = 0;    ///< samples to test (a2c: coverage AND the a2c mask)
  uint64_t survivors = 0;  ///< samples that passed the depth test (S)
  uint32_t m = 0;          ///< popcount(survivors)
  TrackResult tr;          ///< lk: tracker decision
  uint32_t count = 0;      ///< enderton: samples to write
  uint8_t order[64];       ///< lk: survivors sorted by stored depth; enderton: the picks
  int list[64];            ///< enderton: survivor list for the shuffle
  uint32_t ref[64];        ///< lk: alpha references in sort order
  float z[64];             ///< the fragment's depth at each covered sample
};

/// Tokens are recycled: their number is bounded by the FIFOs and windows.
class TokenPool {
 public:
  FragToken* get() {
    if (free_.empty()) {
      all_.push_back(std::make_unique<FragToken>());
      return all_.back().get();
    }
    FragToken* t = free_.back();
    free_.pop_back();
    return t;
  }
  void put(FragToken* t) { free_.push_back(t); }
  size_t allocated() const { return all_.size(); }

 private:
  std::vector<std::unique_ptr<FragToken>> all_;
  std::vector<FragToken*> free_;
};

class PixelOrdering;

struct RopContext {
  RopContext(const TraceHeader& h, const GoldenConfig& g, uint32_t line_bytes);

  TraceHeader header;
  GoldenConfig golden;
  SampleStore store;
  Counters counters;  ///< the same event counts the golden model keeps
  TokenPool pool;
  AddressMap amap;
  uint32_t hilbert_n;
  int tracker_bytes;
  std::array<float, 64> offset_x{}, offset_y{};  ///< sample offsets from the pixel centre
  std::array<uint64_t, 65> a2c_prefix{};
  std::vector<PixelOrdering*> ordering;  ///< per ROP: where a fragment retires

  /// Called when a fragment retires (its pixel leaves the scoreboard).
  std::function<void(const FragToken&, uint64_t cycle)> retire_hook;
  uint64_t retired = 0, last_retire = 0;

  uint64_t fixed_alpha(float alpha) { return memo_.fixed_alpha(alpha); }
  const uint16_t* half_color(const std::array<float, 3>& rgb) { return memo_.half_color(rgb); }
  /// The fragment leaves the ROP at cycle: releases its pixel and its token.
  void retire(FragToken* t, uint64_t cycle);

 private:
  ConversionMemo memo_;
};

}  // namespace ropsim
