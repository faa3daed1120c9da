#include "util/codec/png_encode.h"

#include <png.h>
#include <zlib.h>

#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <new>
#include <string>

namespace ropsim {

namespace {

/// What libpng's callbacks reach: the growing output and the first failure.
struct Sink {
  std::vector<unsigned char>* out;
  char error[256];
};

void on_write(png_structp png, png_bytep data, size_t n) {
  auto* s = static_cast<Sink*>(png_get_io_ptr(png));
  bool full = false;
  try {
    s->out->insert(s->out->end(), data, data + n);
  } catch (const std::bad_alloc&) {
    full = true;
  }
  if (full) png_error(png, "out of memory");  // longjmps: never from inside the handler
}

void on_flush(png_structp) {}

void on_error(png_structp png, png_const_charp msg) {
  auto* s = static_cast<Sink*>(png_get_error_ptr(png));
  if (s->error[0] == '\0') std::snprintf(s->error, sizeof s->error, "%s", msg);
  png_longjmp(png, 1);
}

void on_warning(png_structp, png_const_charp) {}

/// The libpng calls, in a frame with no C++ object to unwind (libpng leaves
/// by longjmp on an error). Returns false with s->error set.
bool write_png(Sink* s, int width, int height, const RowSource* rows, unsigned char* row) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, s, on_error, on_warning);
  if (!png) {
    std::snprintf(s->error, sizeof s->error, "cannot start libpng");
    return false;
  }
  png_infop info = png_create_info_struct(png);
  if (!info || setjmp(png_jmpbuf(png))) {
    if (s->error[0] == '\0') std::snprintf(s->error, sizeof s->error, "cannot start libpng");
    png_destroy_write_struct(&png, info ? &info : nullptr);
    return false;
  }
  png_set_write_fn(png, s, on_write, on_flush);
  // As OpenImageIO's PNG writer sets them for an 8-bit sRGB RGB image: the
  // sRGB intent with its gAMA and cHRM, a zero oFFs, the colour space named
  // in a tEXt chunk, zlib's default level and strategy, and libpng's default
  // row filters.
  png_set_IHDR(png, info, png_uint_32(width), png_uint_32(height), 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_compression_level(png, 6);
  png_set_compression_strategy(png, Z_DEFAULT_STRATEGY);  // libpng would choose Z_FILTERED
  png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_ABSOLUTE);
  png_set_oFFs(png, info, 0, 0, PNG_OFFSET_PIXEL);
  char key[] = "oiio:ColorSpace", value[] = "sRGB";
  png_text text;
  std::memset(&text, 0, sizeof text);
  text.compression = PNG_TEXT_COMPRESSION_NONE;
  text.key = key;
  text.text = value;
  png_set_text(png, info, &text, 1);
  png_write_info(png, info);
  for (int y = 0; y < height; ++y) {
    (*rows)(y, row);
    png_write_row(png, row);
  }
  png_write_end(png, info);
  png_destroy_write_struct(&png, &info);
  return true;
}

}  // namespace

std::vector<unsigned char> encode_png_libpng(int width, int height, const RowSource& rows, const std::string& name) {
  if (width <= 0 || height <= 0) throw ImageCodecError(name + ": cannot encode an empty image");
  std::vector<unsigned char> out;
  std::vector<unsigned char> row(size_t(width) * 3);
  Sink s{&out, {}};
  if (!write_png(&s, width, height, &rows, row.data()))
    throw ImageCodecError(name + ": cannot encode the image: " + s.error);
  return out;
}

}  // namespace ropsim
