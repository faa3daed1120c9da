// Pixels by kind, from a fragment stream: what LK's analysis distinguishes
// (single layer, interior edges of one surface, silhouettes, two layers drawn
// near-to-far or far-to-near, many layers), and an image's error against a
// reference within each kind. docs/results.md uses it to explain where lk's
// advantage over enderton comes from.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "rtl_models/functional/fragment_source.h"
#include "rtl_models/functional/image.h"

namespace ropsim {

enum class PixelKind : uint8_t {
  kEmpty,         ///< no fragment
  kSingle,        ///< one fragment covering every sample
  kInteriorEdge,  ///< several fragments, each sample covered once, all covered (one surface's triangles)
  kSilhouette,    ///< some sample never covered (the background shows)
  kTwoFarToNear,  ///< every sample covered, at most twice, the later layer nearer
  kTwoNearToFar,  ///< every sample covered, at most twice, the later layer farther
  kMany,          ///< every sample covered, some three times or more
};
inline constexpr int kPixelKinds = 7;
const char* to_string(PixelKind k);

/// The kind of every pixel (row-major) of the input's frame.
struct PixelKinds {
  uint32_t width = 0, height = 0;
  std::vector<PixelKind> kind;
  std::array<uint64_t, kPixelKinds> count{};  ///< pixels of each kind
};
/// Streams the input once. Throws TraceError / SceneError for bad input.
PixelKinds classify_pixels(const InputSpec& in);

/// RMSE in 8-bit units of image against reference over the pixels of each
/// kind (0 where a kind has no pixel). The three are of one input: sizes
/// that differ are an InternalError.
std::array<double, kPixelKinds> rmse_by_kind(const PixelKinds& k, const Image& image, const Image& reference);

}  // namespace ropsim
