#include "sim/driver/pixel_kinds.h"

#include <cmath>
#include <stdexcept>

#include "util/errors.h"
#include "util/memory_budget.h"

namespace ropsim {

const char* to_string(PixelKind k) {
  switch (k) {
    case PixelKind::kEmpty:
      return "empty";
    case PixelKind::kSingle:
      return "single layer";
    case PixelKind::kInteriorEdge:
      return "interior edge";
    case PixelKind::kSilhouette:
      return "silhouette";
    case PixelKind::kTwoFarToNear:
      return "two layers, far-to-near";
    case PixelKind::kTwoNearToFar:
      return "two layers, near-to-far";
    case PixelKind::kMany:
      return "many layers";
  }
  return "?";
}

PixelKinds classify_pixels(const InputSpec& in) {
  auto src = open_fragments(in);
  const TraceHeader& h = src->header();
  const size_t n = size_t(h.width) * h.height, spp = size_t(h.spp);
  const uint64_t full = spp == 64 ? ~uint64_t{0} : (uint64_t{1} << spp) - 1;
  struct Pixel {
    uint64_t covered = 0;  // union of the coverage
    uint32_t fragments = 0;
    uint8_t max_count = 0;
    float first_z = 0, last_z = 0;  // depth at the centre of the first and the latest fragment
  };
  // Per pixel of the whole screen (the kinds are a dense map): checked
  // against --memory-limit before it is allocated.
  memory_budget().check_estimate(
      n * (sizeof(Pixel) + spp + sizeof(PixelKind)),
      "the pixel-kind tables of a " + std::to_string(h.width) + " x " + std::to_string(h.height) + " screen");
  std::vector<Pixel> px(n);
  std::vector<uint8_t> count(n * spp, 0);  // fragments per sample (saturating)
  for (Fragment f; src->next(f);) {
    const size_t i = size_t(f.y) * h.width + f.x;
    Pixel& p = px[i];
    uint8_t* c = &count[i * spp];
    for (uint64_t m = f.coverage; m; m &= m - 1) {
      uint8_t& k = c[__builtin_ctzll(m)];
      if (k < 255) ++k;
      if (k > p.max_count) p.max_count = k;
    }
    // The centre depth: the plane's z0, or the mean of the covered samples.
    float z = f.z0;
    if (h.depth_mode == DepthMode::kPerSample) {
      double sum = 0;
      for (uint64_t m = f.coverage; m; m &= m - 1) sum += f.z[size_t(__builtin_ctzll(m))];
      z = float(sum / __builtin_popcountll(f.coverage));
    }
    if (!p.fragments) p.first_z = z;
    p.last_z = z;
    p.covered |= f.coverage;
    ++p.fragments;
  }
  PixelKinds r;
  r.width = h.width;
  r.height = h.height;
  r.kind.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const Pixel& p = px[i];
    PixelKind k;
    if (!p.fragments)
      k = PixelKind::kEmpty;
    else if (p.covered != full)
      k = PixelKind::kSilhouette;
    else if (p.max_count == 1)
      k = p.fragments == 1 ? PixelKind::kSingle : PixelKind::kInteriorEdge;
    else if (p.max_count == 2)
      k = p.last_z < p.first_z ? PixelKind::kTwoFarToNear : PixelKind::kTwoNearToFar;
    else
      k = PixelKind::kMany;
    r.kind[i] = k;
    ++r.count[size_t(k)];
  }
  return r;
}

std::array<double, kPixelKinds> rmse_by_kind(const PixelKinds& k, const Image& image, const Image& reference) {
  if (image.width != k.width || image.height != k.height || reference.width != k.width || reference.height != k.height)
    throw InternalError("pixel kinds: the images and the input differ in size");
  std::array<double, kPixelKinds> sum{}, rmse{};
  for (size_t i = 0; i < k.kind.size(); ++i) {
    const uint32_t x = uint32_t(i % k.width), y = uint32_t(i / k.width);
    const float *a = image.at(x, y), *r = reference.at(x, y);
    for (int c = 0; c < 3; ++c) {
      const double d = double(a[c]) - double(r[c]);
      sum[size_t(k.kind[i])] += d * d;
    }
  }
  for (int j = 0; j < kPixelKinds; ++j)
    rmse[size_t(j)] = k.count[size_t(j)] ? std::sqrt(sum[size_t(j)] / (3.0 * double(k.count[size_t(j)]))) * 255.0 : 0.0;
  return rmse;
}

}  // namespace ropsim
