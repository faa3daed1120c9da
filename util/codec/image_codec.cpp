#include "util/codec/image_codec.h"

#include <dlfcn.h>
#include <unistd.h>

#include <cctype>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <mutex>

#include "util/codec/image_codec_abi.h"
#include "util/codec/png_encode.h"

#ifndef ROPSIM_OIIO_MODULE_BUILD_PATH
#error "ROPSIM_OIIO_MODULE_BUILD_PATH must name the module in the build tree (CMakeLists.txt)"
#endif

namespace ropsim {

namespace {

constexpr const char* kModuleName = "libropsim_oiio.so";

struct Module {
  std::string path;
  decltype(&ropsim_oiio_decode) decode = nullptr;
  decltype(&ropsim_oiio_encode) encode = nullptr;
  decltype(&ropsim_oiio_free) release = nullptr;
  std::string error;  ///< why it could not be loaded
};

std::string executable_dir() {
  std::string buf(4096, '\0');
  const ssize_t n = ::readlink("/proc/self/exe", buf.data(), buf.size() - 1);
  if (n <= 0) return "";
  buf.resize(size_t(n));
  const auto slash = buf.find_last_of('/');
  return slash == std::string::npos ? std::string() : buf.substr(0, slash);
}

Module load() {
  Module m;
  std::vector<std::string> candidates;
  if (const char* env = std::getenv("ROPSIM_OIIO_MODULE"); env && *env) {
    candidates.emplace_back(env);  // an explicit choice: the only one tried
  } else {
    const std::string dir = executable_dir();
    if (!dir.empty()) {
      candidates.push_back(dir + "/" + kModuleName);
      candidates.push_back(dir + "/../lib/ropsim/" + kModuleName);
    }
    candidates.emplace_back(ROPSIM_OIIO_MODULE_BUILD_PATH);
  }
  std::string tried;
  for (const auto& c : candidates) {
    if (::access(c.c_str(), F_OK) != 0) {
      tried += (tried.empty() ? "" : ", ") + c;
      continue;
    }
    void* h = ::dlopen(c.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!h) {
      m.error = std::string("cannot load the image module ") + c + ": " + ::dlerror();
      return m;
    }
    auto version = reinterpret_cast<decltype(&ropsim_oiio_abi_version)>(::dlsym(h, "ropsim_oiio_abi_version"));
    m.decode = reinterpret_cast<decltype(&ropsim_oiio_decode)>(::dlsym(h, "ropsim_oiio_decode"));
    m.encode = reinterpret_cast<decltype(&ropsim_oiio_encode)>(::dlsym(h, "ropsim_oiio_encode"));
    m.release = reinterpret_cast<decltype(&ropsim_oiio_free)>(::dlsym(h, "ropsim_oiio_free"));
    if (!version || !m.decode || !m.encode || !m.release || version() != ROPSIM_OIIO_ABI_VERSION) {
      m = Module{};
      m.error = "the image module " + c + " is not this ropsim's (interface version " +
                std::to_string(ROPSIM_OIIO_ABI_VERSION) + ")";
      return m;
    }
    m.path = c;
    return m;  // never unloaded: OpenImageIO keeps threads and plugins
  }
  m.error = std::string("cannot find the image module ") + kModuleName + " (looked at " + tried +
            "; set ROPSIM_OIIO_MODULE to its path)";
  return m;
}

const Module& module() {
  static std::once_flag once;
  static std::unique_ptr<Module> m;
  std::call_once(once, [] { m = std::make_unique<Module>(load()); });
  if (!m->decode) throw ImageCodecError(m->error);
  return *m;
}

/// The module, or ImageCodecError naming the file the caller was working on.
const Module& module_for(const std::string& name) {
  try {
    return module();
  } catch (const ImageCodecError& e) {
    throw ImageCodecError(name + ": " + e.what());
  }
}

DecodedImage decode(const char* path, const void* data, size_t bytes, const std::string& name) {
  const Module& m = module_for(name);
  DecodedImage img;
  float* px = nullptr;
  char err[512], cs[128];
  int is_float = 0;
  if (m.decode(path, data, bytes, &img.width, &img.height, &img.channels, &px, cs, sizeof cs, &is_float, err,
               sizeof err) != 0)
    throw ImageCodecError(name + ": cannot read the image: " + err);
  img.color_space = cs;
  img.float_pixels = is_float != 0;
  std::unique_ptr<float, decltype(m.release)> owned(px, m.release);
  img.px.assign(px, px + size_t(img.width) * size_t(img.height) * size_t(img.channels));
  return img;
}

void call_rows(void* ctx, int y, void* row) { (*static_cast<const RowSource*>(ctx))(y, row); }

std::vector<unsigned char> encode(int width, int height, const RowSource& rows, const std::string& path) {
  const Module& m = module_for(path);
  unsigned char* out = nullptr;
  size_t n = 0;
  char err[512];
  if (m.encode(path.c_str(), width, height, &call_rows, const_cast<RowSource*>(&rows), &out, &n, err, sizeof err) != 0)
    throw ImageCodecError(path + ": cannot encode the image: " + err);
  std::unique_ptr<unsigned char, decltype(m.release)> owned(out, m.release);
  return std::vector<unsigned char>(out, out + n);
}

}  // namespace

DecodedImage decode_image_file(const std::string& path) { return decode(path.c_str(), nullptr, 0, path); }

DecodedImage decode_image_memory(const void* data, size_t bytes, const std::string& format_hint,
                                 const std::string& name) {
  const std::string fake = "embedded." + (format_hint.empty() ? std::string("png") : format_hint);
  if (!data || bytes == 0) throw ImageCodecError(name + ": empty image data");
  return decode(fake.c_str(), data, bytes, name);
}

std::vector<unsigned char> encode_exr_rows(int width, int height, const RowSource& rows, const std::string& path) {
  if (image_extension(path) != "exr") throw ImageCodecError(path + ": an EXR image needs the extension .exr");
  return encode(width, height, rows, path);
}

std::vector<unsigned char> encode_png_rows(int width, int height, const RowSource& rows, const std::string& path) {
  if (image_extension(path) != "png") throw ImageCodecError(path + ": a PNG image needs the extension .png");
  return encode_png_libpng(width, height, rows, path);
}

std::vector<unsigned char> encode_png_oiio(int width, int height, const RowSource& rows, const std::string& path) {
  if (image_extension(path) != "png") throw ImageCodecError(path + ": a PNG image needs the extension .png");
  return encode(width, height, rows, path);
}

std::vector<unsigned char> encode_exr_rgb(const float* rgb, int width, int height, const std::string& path) {
  return encode_exr_rows(
      width, height,
      [&](int y, void* row) {
        std::memcpy(row, rgb + size_t(y) * size_t(width) * 3, size_t(width) * 3 * sizeof(float));
      },
      path);
}

std::vector<unsigned char> encode_png_rgb8(const unsigned char* rgb8, int width, int height, const std::string& path) {
  return encode_png_rows(
      width, height,
      [&](int y, void* row) { std::memcpy(row, rgb8 + size_t(y) * size_t(width) * 3, size_t(width) * 3); }, path);
}

std::string image_codec_module_path() {
  try {
    return module().path;
  } catch (const ImageCodecError&) {
    return "";
  }
}

}  // namespace ropsim
