// Image decoding and encoding through OpenImageIO, loaded on first use.
//
// OpenImageIO pulls in some 260 shared libraries whose loading costs about
// 0.3 s of CPU at every process start (more than a small simulation). So no
// ropsim binary links it: its code is a module (libropsim_oiio.so,
// image_codec_oiio.cpp) that this loader opens with dlopen() the first time an
// image is read, or an EXR written. A PNG is written with libpng in the
// process (png_encode.h), to the same bytes, so a run that writes PNG images
// only never loads the module.
//
// The module is looked for, in order: $ROPSIM_OIIO_MODULE (a path), beside the
// executable, in ../lib/ropsim next to it (an install), then in the build tree
// it was built in.
#pragma once
#include <cctype>
#include <cstddef>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "util/errors.h"

namespace ropsim {

/// A failure to load the module, decode or encode; the message names the file.
class ImageCodecError : public UserError {
 public:
  using UserError::UserError;
};

/// A decoded image: channels as stored (1 to 4, alpha unassociated: colour is
/// not premultiplied), as float, row by row from the top.
struct DecodedImage {
  int width = 0;
  int height = 0;
  int channels = 0;
  std::vector<float> px;      ///< [(y * width + x) * channels + c], values as stored (code value / max for integers)
  std::string color_space;    ///< as the file names it (OpenImageIO's "oiio:ColorSpace"); empty if it names none
  bool float_pixels = false;  ///< stored as floating point (EXR, HDR), not as integer code values
};

/// Decodes any image OpenImageIO reads. Throws ImageCodecError.
DecodedImage decode_image_file(const std::string& path);
/// Decodes an image held in memory; format_hint is its extension ("png",
/// "jpg", ...; empty: png), name is used in messages. Throws ImageCodecError.
DecodedImage decode_image_memory(const void* data, size_t bytes, const std::string& format_hint,
                                 const std::string& name);

/// Encodes RGB pixels into memory in the format of path's extension: "exr"
/// (rgb are binary32, linear, zip) or "png" (rgb8 are 8-bit code values).
/// No timestamp goes into the metadata, so the same pixels give the same bytes.
/// Throws ImageCodecError.
std::vector<unsigned char> encode_exr_rgb(const float* rgb, int width, int height, const std::string& path);
std::vector<unsigned char> encode_png_rgb8(const unsigned char* rgb8, int width, int height, const std::string& path);

/// Fills row y (from the top) of an image being encoded: width * 3 values,
/// float for EXR, unsigned char for PNG. Must not throw.
using RowSource = std::function<void(int y, void* row)>;
/// The same encodings with the pixels asked for row by row, so an image is
/// never held whole: only one row uncompressed, and the encoded bytes.
std::vector<unsigned char> encode_exr_rows(int width, int height, const RowSource& rows, const std::string& path);
std::vector<unsigned char> encode_png_rows(int width, int height, const RowSource& rows, const std::string& path);

/// The lower-case extension of path's file name, without the dot ("" if none):
/// the format of an image to write.
inline std::string image_extension(const std::string& path) {
  const auto dot = path.find_last_of('.');
  const auto slash = path.find_last_of('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string e = path.substr(dot + 1);
  for (auto& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

/// The module's path once loaded, else empty (for diagnostics and tests).
std::string image_codec_module_path();

}  // namespace ropsim
