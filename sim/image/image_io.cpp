#include "image_io.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "output_file.h"

namespace ropsim {

namespace {

std::string extension_of(const std::string& path) {
  auto dot = path.find_last_of('.');
  auto slash = path.find_last_of('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string e = path.substr(dot + 1);
  for (auto& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

OIIO::ImageBuf to_imagebuf(const Image& img) {
  OIIO::ImageSpec spec(int(img.width), int(img.height), 3, OIIO::TypeDesc::FLOAT);
  OIIO::ImageBuf buf(spec);
  buf.set_pixels(OIIO::ROI::All(), OIIO::TypeDesc::FLOAT, img.rgb.data());
  return buf;
}

}  // namespace

float linear_to_srgb(float v) {
  if (!(v > 0.0f)) return 0.0f;
  if (v >= 1.0f) return 1.0f;
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

std::vector<unsigned char> encode_image(const Image& img, const std::string& path) {
  const std::string ext = extension_of(path);
  if (ext != "exr" && ext != "png")
    throw ImageError(path + ": unsupported image extension '." + ext + "' (use .exr or .png)");
  auto out = OIIO::ImageOutput::create(path);
  if (!out) throw ImageError(path + ": cannot create an image writer: " + OIIO::geterror());
  if (!out->supports("ioproxy")) throw ImageError(path + ": this OpenImageIO cannot encode ." + ext + " into memory");
  const OIIO::TypeDesc type = ext == "exr" ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8;
  OIIO::ImageSpec spec(int(img.width), int(img.height), 3, type);
  std::vector<uint8_t> px;
  const void* data = img.rgb.data();
  if (ext == "exr") {
    spec.attribute("oiio:ColorSpace", "Linear");
    spec.attribute("compression", "zip");
  } else {
    spec.attribute("oiio:ColorSpace", "sRGB");
    px.resize(img.rgb.size());
    for (size_t i = 0; i < px.size(); ++i) px[i] = uint8_t(std::lround(linear_to_srgb(img.rgb[i]) * 255.0f));
    data = px.data();
  }
  // No wall-clock time in the metadata, so the same run gives the same bytes:
  // without a DateTime, OpenImageIO's EXR writer stores the current time as
  // capDate; an empty DateTime is stored as an empty capDate.
  spec.attribute("DateTime", "");
  OIIO::Filesystem::IOVecOutput mem;
  if (!out->set_ioproxy(&mem)) throw ImageError(path + ": cannot encode into memory: " + out->geterror());
  bool ok = out->open(path, spec) && out->write_image(type, data);
  ok = out->close() && ok;
  if (!ok || mem.buffer().empty())
    throw ImageError(path + ": cannot encode the image: " + (ok ? std::string("no bytes") : out->geterror()));
  return std::move(mem.buffer());
}

void write_image(const Image& img, const std::string& path) {
  const std::vector<unsigned char> bytes = encode_image(img, path);
  // Every write checked (OpenImageIO's PNG writer ignores write errors).
  OutputFile file(path);
  file.write(bytes.data(), bytes.size());
  file.commit();
}

Image read_image(const std::string& path) {
  OIIO::ImageBuf buf(path);
  if (!buf.read(0, 0, true, OIIO::TypeDesc::FLOAT)) throw ImageError(path + ": cannot read image: " + buf.geterror());
  const auto& spec = buf.spec();
  if (spec.nchannels < 3)
    throw ImageError(path + ": image has " + std::to_string(spec.nchannels) + " channels, need RGB");
  Image img;
  img.width = uint32_t(spec.width);
  img.height = uint32_t(spec.height);
  img.rgb.resize(size_t(img.width) * img.height * 3);
  OIIO::ROI roi = buf.roi();
  roi.chbegin = 0;
  roi.chend = 3;
  if (!buf.get_pixels(roi, OIIO::TypeDesc::FLOAT, img.rgb.data()))
    throw ImageError(path + ": cannot read pixels: " + buf.geterror());
  return img;
}

CompareResult compare_images(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height)
    throw ImageError("images differ in size: " + std::to_string(a.width) + "x" + std::to_string(a.height) + " vs " +
                     std::to_string(b.width) + "x" + std::to_string(b.height));
  OIIO::ImageBuf A = to_imagebuf(a), B = to_imagebuf(b);
  auto r = OIIO::ImageBufAlgo::compare(A, B, 1e30f, 1e30f);
  if (r.error) throw ImageError("image comparison failed: " + OIIO::geterror());
  CompareResult c;
  c.rmse_8bit = r.rms_error * 255.0;
  c.psnr_db = r.rms_error > 0 ? r.PSNR : std::numeric_limits<double>::infinity();
  c.max_error_8bit = r.maxerror * 255.0;
  c.mean_error_8bit = r.meanerror * 255.0;
  double sum = 0;  // in sample order: deterministic
  for (size_t i = 0; i < a.rgb.size(); ++i) sum += double(a.rgb[i]) - double(b.rgb[i]);
  c.bias_8bit = a.rgb.empty() ? 0.0 : sum / double(a.rgb.size()) * 255.0;
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
