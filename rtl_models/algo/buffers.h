// The ROP's per-pixel surfaces (buffers), named once for the address map,
// the caches' statistics and surface compression.
#pragma once

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

}  // namespace ropsim
