// The ROP's per-pixel surfaces (buffers), named once for the address map,
// the caches' statistics and surface compression.
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>

#include "rtl_models/algo/blend.h"
#include "rtl_models/algo/numerics.h"

namespace ropsim {

enum class Buffer : int { kDepth, kColor, kTracker, kTransmittance, kAccum, kLayers };
constexpr int kBuffers = 6;
/// The buffers every method's report lists (the render targets and slab's
/// layers only when the method has them).
constexpr int kBaseBuffers = 3;
inline const char* to_string(Buffer b) {
  switch (b) {
    case Buffer::kDepth:
      return "depth";
    case Buffer::kColor:
      return "color";
    case Buffer::kTracker:
      return "tracker";
    case Buffer::kTransmittance:
      return "transmittance";
    case Buffer::kAccum:
      return "accum";
    case Buffer::kLayers:
      return "layers";
  }
  return "?";
}

/// Bytes of one sample of each per-sample surface (depth, colour and the
/// render targets; 0 for the per-pixel tracker and layers).
using SampleBytes = std::array<uint32_t, kBuffers>;
/// The sizes of a frame without draw states: depth 4, colour 6, the render
/// targets in formats f.
inline SampleBytes plain_sample_bytes(const BlendFormats& f = {}) {
  SampleBytes b{};
  b[size_t(Buffer::kDepth)] = kDepthSampleBytes;
  b[size_t(Buffer::kColor)] = kColorSampleBytes;
  b[size_t(Buffer::kTransmittance)] = sample_bytes(f.transmittance);
  b[size_t(Buffer::kAccum)] = sample_bytes(f.accum);
  return b;
}

}  // namespace ropsim
