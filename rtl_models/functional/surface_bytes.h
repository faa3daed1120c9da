// The bytes of one sample of each per-sample surface in the modelled
// memory, against the functional store's bytes (sample_store.h).
//
// The store keeps depth in binary32, the methods' colour buffer in RGB
// binary16 and blend's framebuffer in RGBA binary32, whatever the frame's
// target. The modelled memory stores them as a GPU does:
// - on a frame without draw states, or of a float target, as the store does
//   (depth 4, colour 6, blend's framebuffer 16 bytes a sample);
// - on a frame of an 8-bit target (unorm8, srgb8), the colour buffer and
//   blend's framebuffer are the application's RGBA8 target: 4 bytes a
//   sample, each channel's 8-bit code (alpha 255 where the colour buffer
//   keeps none, docs/methods.md);
// - the methods' own render targets (transmittance, accum) in the design's
//   formats, as the store does.
// The address map, the byte counters and surface compression all use
// `stored`; compression sees the bytes `store` makes.
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>

#include "rtl_models/algo/buffers.h"
#include "rtl_models/functional/sample_store.h"
#include "traces/format/draw_state.h"

namespace ropsim {

struct SurfaceBytes {
  /// Bytes of one sample in memory, per per-sample surface (the render
  /// targets' whether the run uses them or not); 0 for the per-pixel
  /// surfaces (tracker, layers).
  SampleBytes stored{};
  /// The same in the functional store.
  SampleBytes host{};
  TargetEncoding encoding = TargetEncoding::kFloat;  ///< the frame's target (frame_encoding)

  uint32_t of(Buffer b) const { return stored[size_t(b)]; }
  /// Does memory hold surface b's samples as other bytes than the store's?
  bool converts(Buffer b) const { return stored[size_t(b)] != host[size_t(b)]; }
  /// Writes n samples of surface b (the store's bytes, host) as memory holds
  /// them (n * of(b) bytes at out). Only for a surface that converts.
  void store(Buffer b, const uint8_t* host_bytes, size_t n, uint8_t* out) const;
};

/// The surfaces of a run over frame h whose store holds targets t.
SurfaceBytes surface_bytes(const TraceHeader& h, const StoreTargets& t);

}  // namespace ropsim
