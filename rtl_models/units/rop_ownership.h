// Which ROP unit owns a pixel: the distributor's rule (distributor.h), also
// used without the SystemC units by the sampled simulation's tag-only warming
// and the analytical model (sim/fidelity/approximate/approximate.h). No SystemC here.
#pragma once
#include <cstdint>

#include "rtl_models/algo/bits.h"
#include "rtl_models/config/hw_config.h"

namespace ropsim {

/// Which ROP unit owns pixel (x, y) on a screen `screen_width` wide: the
/// distributor's rule (also the sampled simulation's tag-only warming).
class RopOwnership {
 public:
  RopOwnership(const HwConfig::Distributor& cfg, uint32_t screen_width)
      : interleave_(cfg.interleave),
        units_(cfg.rop_units),
        tile_shift_(uint32_t(log2_ceil(cfg.tile_pixels))),
        tiles_x_(ceil_div(screen_width, cfg.tile_pixels)) {}
  /// The screen tile holding pixel (x, y): ty * tiles_x + tx.
  uint32_t tile_of(uint32_t x, uint32_t y) const { return (y >> tile_shift_) * tiles_x_ + (x >> tile_shift_); }
  uint32_t tiles_x() const { return tiles_x_; }
  uint32_t rop_of(uint32_t x, uint32_t y) const {
    const uint32_t tx = x >> tile_shift_, ty = y >> tile_shift_;
    return interleave_ == Interleave::kDiagonal ? (tx + ty) % units_
                                                : uint32_t((uint64_t(ty) * tiles_x_ + tx) % units_);
  }

 private:
  Interleave interleave_;
  uint32_t units_, tile_shift_, tiles_x_;
};

}  // namespace ropsim
