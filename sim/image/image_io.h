// Image files: linear EXR and sRGB PNG, encoded in memory (through
// OpenImageIO, loaded on first use: util/codec/image_codec.h) and written
// through OutputFile (util/output_file.h), so a failure (a full disk included)
// is an error and leaves no partial file; any readable image read back; and
// image comparison.
#pragma once
#include <stdexcept>
#include <string>
#include <vector>

#include "image.h"

namespace ropsim {

class ImageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Encodes img by the extension of path (.exr: linear binary32 RGB, zip;
/// .png: sRGB 8-bit) into memory, with no timestamp in its metadata (the same
/// image gives the same bytes). Throws ImageError.
std::vector<unsigned char> encode_image(const Image& img, const std::string& path);

/// encode_image, then written through OutputFile (UserError on a write error).
void write_image(const Image& img, const std::string& path);

/// Reads any OpenImageIO-readable image as float RGB, values as stored
/// (an 8-bit PNG gives its code values / 255, an EXR its linear values;
/// colour is not premultiplied by an alpha channel).
Image read_image(const std::string& path);

struct CompareResult {
  double rmse_8bit = 0;  ///< RMSE over all pixels and RGB channels, x 255
  double psnr_db = 0;    ///< 20 log10(1 / RMSE) with RMSE in [0, 1] units
  double max_error_8bit = 0;
  double mean_error_8bit = 0;
  double bias_8bit = 0;  ///< mean signed error (a minus b) over all pixels and RGB channels, x 255
};

/// Compares two images of the same size over every pixel and RGB channel.
CompareResult compare_images(const Image& a, const Image& b);
CompareResult compare_image_files(const std::string& a, const std::string& b);

/// Linear -> sRGB transfer function (IEC 61966-2-1), input clamped to [0, 1].
float linear_to_srgb(float v);

}  // namespace ropsim
