// Image files: linear EXR and sRGB PNG, encoded in memory (through
// OpenImageIO, loaded on first use: util/codec/image_codec.h) and written
// through OutputFile (util/output_file.h), so a failure (a full disk included)
// is an error and leaves no partial file; any readable image read back; and
// image comparison.
#pragma once
#include <stdexcept>
#include <string>
#include <vector>

#include "rtl_models/functional/image.h"
#include "util/errors.h"

namespace ropsim {

class ImageError : public UserError {
 public:
  using UserError::UserError;
};

/// Encodes img by the extension of path (.exr: linear binary32 RGB, zip;
/// .png: sRGB 8-bit) into memory, with no timestamp in its metadata (the same
/// image gives the same bytes). Throws ImageError.
std::vector<unsigned char> encode_image(const Image& img, const std::string& path);

/// encode_image, then written through OutputFile (UserError on a write error).
void write_image(const Image& img, const std::string& path);

/// How an image file encodes light: linear values (EXR) or sRGB code values
/// (an 8-bit PNG).
enum class Transfer { kLinear, kSrgb };
const char* to_string(Transfer t);

/// The transfer of a decoded file: its named colour space when it names one
/// ("linear", "lin_srgb", "scene_linear" -> linear; "sRGB", "srgb_texture"
/// -> sRGB), else linear for floating-point pixels and sRGB for integer code
/// values. Any other named space (a gamma, Rec. 709, ACES...) is refused:
/// ImageError naming the file.
Transfer transfer_of(const std::string& path, const std::string& color_space, bool float_pixels);

/// sRGB -> linear transfer function (IEC 61966-2-1), the inverse of
/// linear_to_srgb.
float srgb_to_linear(float v);

/// Reads any OpenImageIO-readable image as linear float RGB: an EXR's values
/// as stored, an sRGB PNG's code values / 255 through srgb_to_linear (colour
/// is not premultiplied by an alpha channel). *transfer, if given, receives
/// the file's own transfer.
Image read_image(const std::string& path, Transfer* transfer = nullptr);

struct CompareResult {
  double rmse_8bit = 0;  ///< RMSE over all pixels and RGB channels, x 255
  double psnr_db = 0;    ///< 20 log10(1 / RMSE) with RMSE in [0, 1] units
  double max_error_8bit = 0;
  double mean_error_8bit = 0;
  double bias_8bit = 0;  ///< mean signed error (a minus b) over all pixels and RGB channels, x 255
};

/// Compares two images of the same size over every pixel and RGB channel.
CompareResult compare_images(const Image& a, const Image& b);

/// Two image files compared in linear light (read_image converts each), as
/// the run report compares an image with its reference; the files' own
/// transfers are returned for the caller to show.
struct FileComparison {
  CompareResult result;
  Transfer a = Transfer::kLinear, b = Transfer::kLinear;
};
FileComparison compare_image_files(const std::string& a, const std::string& b);

/// Linear -> sRGB transfer function (IEC 61966-2-1), input clamped to [0, 1].
float linear_to_srgb(float v);

}  // namespace ropsim
