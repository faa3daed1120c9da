// What a unit's functional write replaces in a surface the compressor tracks
// (compression_model.h): the pixel's bytes as memory holds them
// (surface_bytes.h), taken before the write, and the part of them each
// posted line write carries as its patch; for depth, with the samples' plane
// keys when the store keeps them (the rasterizer-plane encoder).
#pragma once
#include <array>
#include <cstdint>
#include <cstring>

#include "rtl_models/functional/surface_bytes.h"
#include "rtl_models/memory/address_map.h"
#include "rtl_models/memory/compression_model.h"

namespace ropsim {

class PixelSnapshot {
 public:
  /// Takes the pixel's bytes of surface b when cm tracks it (ptr: the
  /// functional store's bytes of the pixel in b; sb: how memory holds them;
  /// planes: depth's plane keys, spp of them, or nullptr).
  void take(CompressionModel* cm, const AddressMap& amap, const SurfaceBytes& sb, Buffer b, uint32_t x, uint32_t y,
            const void* ptr, const uint64_t* planes = nullptr) {
    cm_ = cm && cm->tracks(b) ? cm : nullptr;
    if (!cm_) return;
    has_planes_ = planes != nullptr;
    if (planes) std::memcpy(planes_.data(), planes, amap.pixel_bytes(b) / kDepthSampleBytes * sizeof(uint64_t));
    b_ = b;
    addr_ = amap.pixel_address(b, x, y);
    bytes_ = amap.pixel_bytes(b);
    if (sb.converts(b))
      sb.store(b, static_cast<const uint8_t*>(ptr), bytes_ / sb.of(b), old_.data());
    else
      std::memcpy(old_.data(), ptr, bytes_);
  }
  /// The patch of a posted write of `line` (CompressionModel::kNoPatch when untracked).
  uint32_t patch(uint64_t line) const {
    return cm_ ? cm_->pend(line, b_, addr_, bytes_, old_.data(), has_planes_ ? planes_.data() : nullptr)
               : CompressionModel::kNoPatch;
  }

 private:
  CompressionModel* cm_ = nullptr;
  Buffer b_ = Buffer::kDepth;
  uint64_t addr_ = 0;
  uint32_t bytes_ = 0;
  std::array<uint8_t, 64 * 16> old_;  // 64 samples of at most 16 bytes (RGBA32F)
  bool has_planes_ = false;
  std::array<uint64_t, 64> planes_;
};

}  // namespace ropsim
