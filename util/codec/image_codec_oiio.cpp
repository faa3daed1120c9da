// The OpenImageIO module (libropsim_oiio.so): the only code that links
// OpenImageIO. Loaded on first use by image_codec.cpp through the C interface
// of image_codec_abi.h.
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <cstdlib>
#include <cstring>
#include <exception>
#include <memory>
#include <string>
#include <vector>

#include "util/codec/image_codec.h"
#include "util/codec/image_codec_abi.h"

namespace {

int fail(char* err, size_t err_size, const std::string& msg) {
  if (err && err_size) {
    const size_t n = std::min(msg.size(), err_size - 1);
    std::memcpy(err, msg.data(), n);
    err[n] = '\0';
  }
  return 1;
}

/// Straight (not premultiplied) alpha: OpenImageIO premultiplies PNG / TGA
/// colour by alpha unless asked not to.
OIIO::ImageSpec straight_alpha() {
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  return config;
}

}  // namespace

extern "C" {

__attribute__((visibility("default"))) int ropsim_oiio_abi_version(void) { return ROPSIM_OIIO_ABI_VERSION; }

__attribute__((visibility("default"))) void ropsim_oiio_free(void* p) { std::free(p); }

__attribute__((visibility("default"))) int ropsim_oiio_decode(const char* path, const void* data, size_t bytes,
                                                              int* width, int* height, int* channels, float** px,
                                                              char* color_space, size_t cs_size, int* is_float,
                                                              char* err, size_t err_size) try {
  *px = nullptr;
  if (color_space && cs_size) color_space[0] = '\0';
  *is_float = 0;
  const OIIO::ImageSpec config = straight_alpha();
  // From memory: OpenImageIO 2.4's ImageInput::open(name, config, proxy)
  // still opens the named file; the reader must get the proxy before open().
  OIIO::Filesystem::IOMemReader mem(data, bytes);
  std::unique_ptr<OIIO::ImageInput> in;
  OIIO::ImageSpec spec;
  if (data) {
    OIIO::Filesystem::IOProxy* proxy = &mem;
    in = OIIO::ImageInput::create(path, false, &config, proxy);
    if (!in) return fail(err, err_size, OIIO::geterror());
    if (!in->supports("ioproxy") || !in->set_ioproxy(proxy))
      return fail(err, err_size, "this OpenImageIO cannot decode this format from memory");
    if (!in->open(path, spec, config)) return fail(err, err_size, in->geterror());
  } else {
    in = OIIO::ImageInput::open(path, &config);
    if (!in) return fail(err, err_size, OIIO::geterror());
    spec = in->spec();
  }
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0) return fail(err, err_size, "empty image");
  const size_t n = size_t(spec.width) * size_t(spec.height) * size_t(spec.nchannels);
  float* p = static_cast<float*>(std::malloc(n * sizeof(float)));
  if (!p) return fail(err, err_size, "out of memory");
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, p)) {
    std::free(p);
    return fail(err, err_size, in->geterror());
  }
  *width = spec.width;
  *height = spec.height;
  *channels = spec.nchannels;
  *px = p;
  *is_float = spec.format.is_floating_point() ? 1 : 0;
  const std::string cs = spec.get_string_attribute("oiio:ColorSpace");
  if (color_space && cs_size) {
    const size_t n = std::min(cs.size(), cs_size - 1);
    std::memcpy(color_space, cs.data(), n);
    color_space[n] = '\0';
  }
  return 0;
} catch (const std::exception& e) {
  return fail(err, err_size, e.what());
}

__attribute__((visibility("default"))) int ropsim_oiio_encode(const char* path, int width, int height,
                                                              ropsim_oiio_row_fn rows, void* ctx, unsigned char** out,
                                                              size_t* out_bytes, char* err, size_t err_size) try {
  *out = nullptr;
  *out_bytes = 0;
  const std::string ext = ropsim::image_extension(path);
  if (ext != "exr" && ext != "png") return fail(err, err_size, "unsupported image extension '." + ext + "'");
  auto o = OIIO::ImageOutput::create(path);
  if (!o) return fail(err, err_size, "cannot create an image writer: " + OIIO::geterror());
  if (!o->supports("ioproxy")) return fail(err, err_size, "this OpenImageIO cannot encode ." + ext + " into memory");
  const OIIO::TypeDesc type = ext == "exr" ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8;
  OIIO::ImageSpec spec(width, height, 3, type);
  if (ext == "exr") {
    spec.attribute("oiio:ColorSpace", "Linear");
    spec.attribute("compression", "zip");
  } else {
    spec.attribute("oiio:ColorSpace", "sRGB");
  }
  // No wall-clock time in the metadata, so the same pixels give the same
  // bytes: without a DateTime, OpenImageIO's EXR writer stores the current
  // time as capDate; an empty DateTime is stored as an empty capDate.
  spec.attribute("DateTime", "");
  OIIO::Filesystem::IOVecOutput mem;
  if (!o->set_ioproxy(&mem)) return fail(err, err_size, "cannot encode into memory: " + o->geterror());
  bool ok = o->open(path, spec);
  std::vector<unsigned char> row(size_t(width) * 3 * type.size());
  for (int y = 0; ok && y < height; ++y) {
    rows(ctx, y, row.data());
    ok = o->write_scanline(y, 0, type, row.data());
  }
  ok = o->close() && ok;
  if (!ok || mem.buffer().empty()) return fail(err, err_size, ok ? std::string("no bytes") : o->geterror());
  const auto& b = mem.buffer();
  unsigned char* p = static_cast<unsigned char*>(std::malloc(b.size()));
  if (!p) return fail(err, err_size, "out of memory");
  std::memcpy(p, b.data(), b.size());
  *out = p;
  *out_bytes = b.size();
  return 0;
} catch (const std::exception& e) {
  return fail(err, err_size, e.what());
}
}
