// PNG encoding with libpng in ropsim's own process: the format of every image
// ropsim writes most often, without loading OpenImageIO's module and its ~260
// shared libraries (image_codec.h). The bytes are those OpenImageIO's PNG
// writer gives for the same pixels (the same libpng calls, chunks and
// settings), which Codec.PngEncoderWritesOpenImageIOsBytes checks, so an
// image's file does not depend on which of the two wrote it.
#pragma once
#include <vector>

#include "util/codec/image_codec.h"

namespace ropsim {

/// RGB, 8 bits a channel, width * 3 code values a row from the top, sRGB.
/// Throws ImageCodecError naming `name`.
std::vector<unsigned char> encode_png_libpng(int width, int height, const RowSource& rows, const std::string& name);

/// The same image through OpenImageIO's module (for the equality test and
/// for comparing the two writers).
std::vector<unsigned char> encode_png_oiio(int width, int height, const RowSource& rows, const std::string& path);

}  // namespace ropsim
