#include "traces/capture/texture.h"

#include <cmath>

#include "traces/capture/scene_file.h"
#include "util/codec/image_codec.h"

namespace ropsim {

namespace {

float srgb_to_linear(float c) { return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f); }

Texture convert(const DecodedImage& d, const std::string& name, bool srgb) {
  const std::vector<float>& px = d.px;
  Texture t;
  t.name = name;
  t.width = d.width;
  t.height = d.height;
  t.rgba.resize(size_t(t.width) * size_t(t.height) * 4);
  const int nc = d.channels;
  for (size_t i = 0; i < size_t(t.width) * size_t(t.height); ++i) {
    const float* p = &px[i * size_t(nc)];
    float r = p[0], g = nc >= 3 ? p[1] : p[0], b = nc >= 3 ? p[2] : p[0];
    float a = nc == 4 ? p[3] : nc == 2 ? p[1] : 1.0f;
    if (srgb) {
      r = srgb_to_linear(r);
      g = srgb_to_linear(g);
      b = srgb_to_linear(b);
    }
    float* o = &t.rgba[i * 4];
    o[0] = std::isfinite(r) ? std::max(r, 0.0f) : 0.0f;
    o[1] = std::isfinite(g) ? std::max(g, 0.0f) : 0.0f;
    o[2] = std::isfinite(b) ? std::max(b, 0.0f) : 0.0f;
    o[3] = std::isfinite(a) ? std::min(std::max(a, 0.0f), 1.0f) : 1.0f;
  }
  return t;
}

}  // namespace

std::array<float, 4> Texture::sample(double u, double v) const {
  // Texel space, y down from the top row.
  const double x = u * width - 0.5, y = (1.0 - v) * height - 0.5;
  const double fx = std::floor(x), fy = std::floor(y);
  const double ax = x - fx, ay = y - fy;
  auto wrap = [](long long i, int n) { return int(((i % n) + n) % n); };
  const int x0 = wrap((long long)fx, width), x1 = wrap((long long)fx + 1, width);
  const int y0 = wrap((long long)fy, height), y1 = wrap((long long)fy + 1, height);
  std::array<float, 4> out{};
  for (int c = 0; c < 4; ++c) {
    auto at = [&](int xi, int yi) { return double(rgba[(size_t(yi) * size_t(width) + size_t(xi)) * 4 + size_t(c)]); };
    const double top = at(x0, y0) * (1 - ax) + at(x1, y0) * ax, bot = at(x0, y1) * (1 - ax) + at(x1, y1) * ax;
    out[size_t(c)] = float(top * (1 - ay) + bot * ay);
  }
  return out;
}

Texture load_texture_file(const std::string& path, bool srgb) {
  try {
    return convert(decode_image_file(path), path, srgb);
  } catch (const ImageCodecError& e) {
    throw CaptureError(e.what());
  }
}

Texture load_texture_memory(const void* data, size_t bytes, const std::string& hint, const std::string& name,
                            bool srgb) {
  try {
    return convert(decode_image_memory(data, bytes, hint, name), name, srgb);
  } catch (const ImageCodecError& e) {
    throw CaptureError(e.what());
  }
}

}  // namespace ropsim
