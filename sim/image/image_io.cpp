#include "sim/image/image_io.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "util/codec/image_codec.h"
#include "util/output_file.h"

namespace ropsim {

float linear_to_srgb(float v) {
  if (!(v > 0.0f)) return 0.0f;
  if (v >= 1.0f) return 1.0f;
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

float srgb_to_linear(float v) {
  if (!(v > 0.0f)) return 0.0f;
  if (v >= 1.0f) return 1.0f;
  return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

const char* to_string(Transfer t) { return t == Transfer::kSrgb ? "sRGB" : "linear"; }

Transfer transfer_of(const std::string& path, const std::string& color_space, bool float_pixels) {
  std::string cs;
  for (char ch : color_space) cs += char(std::tolower(static_cast<unsigned char>(ch)));
  if (cs.empty()) return float_pixels ? Transfer::kLinear : Transfer::kSrgb;
  if (cs == "linear" || cs == "lin_srgb" || cs == "scene_linear" || cs == "lin_rec709") return Transfer::kLinear;
  if (cs == "srgb" || cs == "srgb_texture" || cs == "srgb_rec709_scene") return Transfer::kSrgb;
  throw ImageError(path + ": colour space '" + color_space +
                   "' is neither linear nor sRGB; convert the image to a linear EXR or an sRGB PNG first");
}

std::vector<unsigned char> encode_image(const Image& img, const std::string& path) {
  const std::string ext = image_extension(path);
  if (ext != "exr" && ext != "png")
    throw ImageError(path + ": unsupported image extension '." + ext + "' (use .exr or .png)");
  try {
    // Row by row: the image is sparse (untouched tiles are its background),
    // so only one dense row exists at a time.
    if (ext == "exr")
      return encode_exr_rows(
          int(img.width), int(img.height), [&](int y, void* row) { img.row(uint32_t(y), static_cast<float*>(row)); },
          path);
    std::vector<float> linear(size_t(img.width) * 3);
    return encode_png_rows(
        int(img.width), int(img.height),
        [&](int y, void* row) {
          img.row(uint32_t(y), linear.data());
          auto* px = static_cast<unsigned char*>(row);
          for (size_t i = 0; i < linear.size(); ++i) px[i] = uint8_t(std::lround(linear_to_srgb(linear[i]) * 255.0f));
        },
        path);
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

Image read_image(const std::string& path, Transfer* transfer) {
  DecodedImage d;
  try {
    d = decode_image_file(path);
  } catch (const ImageCodecError& e) {
    throw ImageError(e.what());
  }
  if (d.channels < 3) throw ImageError(path + ": image has " + std::to_string(d.channels) + " channels, need RGB");
  const Transfer t = transfer_of(path, d.color_space, d.float_pixels);
  if (transfer) *transfer = t;
  Image img(uint32_t(d.width), uint32_t(d.height));
  for (uint32_t y = 0; y < img.height; ++y)
    for (uint32_t x = 0; x < img.width; ++x) {
      const float* p = &d.px[(size_t(y) * img.width + x) * size_t(d.channels)];
      float* o = img.at(x, y);
      for (size_t c = 0; c < 3; ++c) o[c] = t == Transfer::kSrgb ? srgb_to_linear(p[c]) : p[c];
    }
  return img;
}

CompareResult compare_images(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height)
    throw ImageError("images differ in size: " + std::to_string(a.width) + "x" + std::to_string(a.height) + " vs " +
                     std::to_string(b.width) + "x" + std::to_string(b.height));
  // Every sum in sample order, in double: deterministic.
  // Row by row in raster order (the images are sparse; one row each is dense).
  double sum = 0, sum_abs = 0, sum_sq = 0, max_abs = 0;
  std::vector<float> ra(size_t(a.width) * 3), rb(ra.size());
  // A row both images left untouched, with equal backgrounds, adds exact
  // zeros to every sum (x + 0.0 == x): skipped, the sums stay bit-identical.
  const bool same_background = a.background() == b.background();
  for (uint32_t y = 0; y < a.height; ++y) {
    if (same_background && a.row_untouched(y) && b.row_untouched(y)) continue;
    a.row(y, ra.data());
    b.row(y, rb.data());
    for (size_t i = 0; i < ra.size(); ++i) {
      const double d = double(ra[i]) - double(rb[i]);
      sum += d;
      sum_abs += std::fabs(d);
      sum_sq += d * d;
      max_abs = std::max(max_abs, std::fabs(d));
    }
  }
  const double n = double(a.width) * double(a.height) * 3.0;
  CompareResult c;
  const double rms = n > 0 ? std::sqrt(sum_sq / n) : 0.0;
  c.rmse_8bit = rms * 255.0;
  c.psnr_db = rms > 0 ? 20.0 * std::log10(1.0 / rms) : std::numeric_limits<double>::infinity();
  c.max_error_8bit = max_abs * 255.0;
  c.mean_error_8bit = n > 0 ? sum_abs / n * 255.0 : 0.0;
  c.bias_8bit = n > 0 ? sum / n * 255.0 : 0.0;
  return c;
}

FileComparison compare_image_files(const std::string& a, const std::string& b) {
  FileComparison fc;
  const Image ia = read_image(a, &fc.a), ib = read_image(b, &fc.b);
  try {
    fc.result = compare_images(ia, ib);
    return fc;
  } catch (const ImageError& e) {
    throw ImageError(a + " vs " + b + ": " + e.what());
  }
}

}  // namespace ropsim
