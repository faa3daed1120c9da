// Where the ROP's per-pixel buffers live in memory: surfaces (depth, colour,
// tracker, the blend methods' transmittance and accumulation render targets,
// and slab's layers), each laid out in 8 x 8-pixel tiles, pixel-major inside a
// tile and sample-major inside a pixel. A per-sample surface's sample takes
// the bytes the run's surfaces give it (surface_bytes.h; without draw
// states depth is binary32, 4 bytes, colour RGB binary16, 6 bytes, and the
// render targets their format's bytes, blend.h), the tracker
// ceil((spp + id bits) / 8) bytes per pixel, slab's layers slab_pixel_bytes
// per pixel. Buffers are 2^48 bytes apart.
#pragma once
#include <cstdint>

#include "rtl_models/algo/bits.h"
#include "rtl_models/algo/blend.h"
#include "rtl_models/algo/buffers.h"
#include "rtl_models/algo/numerics.h"

namespace ropsim {

class AddressMap {
 public:
  AddressMap(uint32_t width, int spp, uint32_t tracker_bytes, uint32_t line_bytes,
             const SampleBytes& bytes = plain_sample_bytes(), uint32_t layer_bytes = 0)
      : tiles_x_(ceil_div(width, 8u)),
        spp_(uint32_t(spp)),
        tracker_bytes_(tracker_bytes),
        layer_bytes_(layer_bytes),
        line_shift_(log2_ceil(line_bytes)),
        bytes_(bytes) {}
  uint64_t pixel_index(uint32_t x, uint32_t y) const {
    return (uint64_t(y >> 3) * tiles_x_ + (x >> 3)) * 64 + ((y & 7u) << 3 | (x & 7u));
  }
  static uint64_t base(Buffer b) { return uint64_t(b) << 48; }
  /// Bytes of a sample of the per-sample surfaces (depth, colour, render targets).
  uint64_t bytes_per_sample(Buffer b) const { return bytes_[size_t(b)]; }
  /// The address of pixel (x, y)'s first sample in a per-sample surface, and its bytes.
  uint64_t pixel_address(Buffer b, uint32_t x, uint32_t y) const {
    return base(b) + pixel_index(x, y) * spp_ * bytes_per_sample(b);
  }
  uint32_t pixel_bytes(Buffer b) const { return uint32_t(spp_ * bytes_per_sample(b)); }

  /// Calls f(line_address) once for every cache line holding a sample of the
  /// mask in the depth or colour buffer, in increasing address order.
  template <class F>
  void for_each_sample_line(Buffer b, uint32_t x, uint32_t y, uint64_t mask, F&& f) const {
    const uint64_t bps = bytes_per_sample(b);
    const uint64_t start = base(b) + pixel_index(x, y) * spp_ * bps;
    uint64_t last = ~uint64_t{0};
    while (mask) {
      const uint64_t a = start + uint64_t(__builtin_ctzll(mask)) * bps;
      const uint64_t l0 = a >> line_shift_, l1 = (a + bps - 1) >> line_shift_;
      for (uint64_t l = l0; l <= l1; ++l)
        if (l != last) {
          f(l << line_shift_);
          last = l;
        }
      // Samples lying wholly in lines <= l1 need nothing more; a sample that
      // starts in l1 and crosses into l1 + 1 stays and emits l1 + 1 next.
      const uint64_t past = ((l1 + 1) << line_shift_) - start;
      const uint64_t k = bps == kDepthSampleBytes   ? past / kDepthSampleBytes
                         : bps == kColorSampleBytes ? past / kColorSampleBytes
                                                    : past / bps;  // constant divisors for depth and colour
      mask = k >= 64 ? 0 : mask & (~uint64_t{0} << k);
    }
  }
  /// The same for the pixel's tracker state.
  template <class F>
  void for_each_tracker_line(uint32_t x, uint32_t y, F&& f) const {
    const uint64_t a = base(Buffer::kTracker) + pixel_index(x, y) * tracker_bytes_;
    for (uint64_t l = a >> line_shift_; l <= (a + tracker_bytes_ - 1) >> line_shift_; ++l) f(l << line_shift_);
  }
  /// The same for the pixel's SLAB layers (slab).
  template <class F>
  void for_each_layer_line(uint32_t x, uint32_t y, F&& f) const {
    const uint64_t a = base(Buffer::kLayers) + pixel_index(x, y) * layer_bytes_;
    for (uint64_t l = a >> line_shift_; l <= (a + layer_bytes_ - 1) >> line_shift_; ++l) f(l << line_shift_);
  }

 private:
  uint64_t tiles_x_;
  uint64_t spp_, tracker_bytes_, layer_bytes_;
  int line_shift_;
  SampleBytes bytes_;
};

}  // namespace ropsim
