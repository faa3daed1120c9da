#include "image_io.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "image_codec.h"
#include "output_file.h"

namespace ropsim {

float linear_to_srgb(float v) {
  if (!(v > 0.0f)) return 0.0f;
  if (v >= 1.0f) return 1.0f;
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

std::vector<unsigned char> encode_image(const Image& img, const std::string& path) {
  const std::string ext = image_extension(path);
  if (ext != "exr" && ext != "png")
    throw ImageError(path + ": unsupported image extension '." + ext + "' (use .exr or .png)");
  try {
    if (ext == "exr") return encode_exr_rgb(img.rgb.data(), int(img.width), int(img.height), path);
    std::vector<unsigned char> px(img.rgb.size());
    for (size_t i = 0; i < px.size(); ++i) px[i] = uint8_t(std::lround(linear_to_srgb(img.rgb[i]) * 255.0f));
    return encode_png_rgb8(px.data(), int(img.width), int(img.height), path);
  } catch (const ImageCodecError& e) {
    throw ImageError(e.what());
  }
}

void write_image(const Image& img, const std::string& path) {
  const std::vector<unsigned char> bytes = encode_image(img, path);
  // Every write checked (OpenImageIO's PNG writer ignores write errors).
  OutputFile file(path);
  file.write(bytes.data(), bytes.size());
  file.commit();
}

Image read_image(const std::string& path) {
  DecodedImage d;
  try {
    d = decode_image_file(path);
  } catch (const ImageCodecError& e) {
    throw ImageError(e.what());
  }
  if (d.channels < 3) throw ImageError(path + ": image has " + std::to_string(d.channels) + " channels, need RGB");
  Image img;
  img.width = uint32_t(d.width);
  img.height = uint32_t(d.height);
  img.rgb.resize(size_t(img.width) * img.height * 3);
  for (size_t i = 0; i < size_t(img.width) * img.height; ++i)
    for (size_t c = 0; c < 3; ++c) img.rgb[i * 3 + c] = d.px[i * size_t(d.channels) + c];
  return img;
}

CompareResult compare_images(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height)
    throw ImageError("images differ in size: " + std::to_string(a.width) + "x" + std::to_string(a.height) + " vs " +
                     std::to_string(b.width) + "x" + std::to_string(b.height));
  // Every sum in sample order, in double: deterministic.
  double sum = 0, sum_abs = 0, sum_sq = 0, max_abs = 0;
  for (size_t i = 0; i < a.rgb.size(); ++i) {
    const double d = double(a.rgb[i]) - double(b.rgb[i]);
    sum += d;
    sum_abs += std::fabs(d);
    sum_sq += d * d;
    max_abs = std::max(max_abs, std::fabs(d));
  }
  const double n = double(a.rgb.size());
  CompareResult c;
  const double rms = n > 0 ? std::sqrt(sum_sq / n) : 0.0;
  c.rmse_8bit = rms * 255.0;
  c.psnr_db = rms > 0 ? 20.0 * std::log10(1.0 / rms) : std::numeric_limits<double>::infinity();
  c.max_error_8bit = max_abs * 255.0;
  c.mean_error_8bit = n > 0 ? sum_abs / n * 255.0 : 0.0;
  c.bias_8bit = n > 0 ? sum / n * 255.0 : 0.0;
  return c;
}

CompareResult compare_image_files(const std::string& a, const std::string& b) {
  const Image ia = read_image(a), ib = read_image(b);
  try {
    return compare_images(ia, ib);
  } catch (const ImageError& e) {
    throw ImageError(a + " vs " + b + ": " + e.what());
  }
}

}  // namespace ropsim
