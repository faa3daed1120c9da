// Cross-check of the capture rasterizer against a real one: Mesa's llvmpipe
// through OSMesa (OpenGL 4.5 core, a multisampled framebuffer). A fragment
// shader appends (pixel, gl_PrimitiveID, gl_SampleMaskIn, gl_FragCoord.z) to
// a shader storage buffer with an atomic counter; API order is restored by
// sorting on (draw, primitive id, y, x). docs/capture.md "Cross-check".
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "traces/capture/capture.h"

namespace ropsim {

struct MesaRecord {
  uint32_t draw = 0, prim = 0;
  uint16_t x = 0, y = 0;  ///< pixel, y down (row 0 at the top, as in traces)
  uint64_t mask = 0;      ///< gl_SampleMaskIn[0]
  float z = 0;            ///< gl_FragCoord.z (the pixel centre)
};

struct MesaCapture {
  std::string renderer, version;
  int samples = 0;                                     ///< GL_SAMPLES of the framebuffer
  std::vector<std::array<float, 2>> sample_positions;  ///< glGetMultisamplefv, pixel units
  std::vector<MesaRecord> records;                     ///< one per (draw, prim, pixel), API order
  uint64_t invocations = 0;                            ///< fragment shader invocations recorded
};

/// Renders the prepared scene (its clip-space triangles, draw by draw) with
/// OSMesa / llvmpipe at `samples` samples per pixel. Throws CaptureError when
/// no GL 4.5 core context or no such multisampled framebuffer can be made.
MesaCapture mesa_capture(const PreparedScene& ps, int samples = 4);

/// The depth tolerance of the cross-check, |ropsim z0 - Mesa gl_FragCoord.z| <=
/// kDepthTolAbs + kDepthTolPixels * (|dzdx| + |dzdy|): 1e-6 in depth units
/// plus the depth change over 1/1000 pixel (binary32 plane set-up of slivers).
/// docs/capture.md explains the values.
inline constexpr double kDepthTolAbs = 1e-6;
inline constexpr double kDepthTolPixels = 1e-3;

struct CrossCheckResult {
  std::string scene, renderer;
  uint32_t width = 0, height = 0;
  int samples = 0;
  std::string positions;        ///< Mesa's positions in 1/256 pixel, as used by ropsim
  uint64_t ours = 0, mesa = 0;  ///< records (draw, prim, pixel) from each
  uint64_t equal = 0;           ///< present in both with the same coverage mask
  uint64_t mask_differs = 0, only_ours = 0, only_mesa = 0;
  double agreement = 0;  ///< equal / records in either
  // Samples whose coverage differs, by the distance of the sample from the
  // nearest edge of ropsim's snapped triangle (1/256 pixel units):
  uint64_t samples_differ = 0, on_edge = 0, within_one_subpixel = 0, farther = 0, in_clipped = 0;
  // Depth at the pixel centre over the records present in both:
  double max_depth_diff = 0, mean_depth_diff = 0;
  uint64_t depth_over_tolerance = 0;
  double ours_seconds = 0, mesa_seconds = 0;
};

/// Prepares the scene, captures it at 4 spp through Mesa and through ropsim's
/// rasterizer with Mesa's sample positions, and compares the records.
CrossCheckResult cross_check_with_mesa(const SceneSpec& spec);
std::string cross_check_summary(const CrossCheckResult& r);

}  // namespace ropsim
