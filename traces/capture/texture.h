// Textures for captures: decoded through OpenImageIO (util/codec, loaded on
// first use; PNG, JPEG, EXR, ...,
// from a file or from memory for glTF-embedded images), held as linear RGBA
// floats, sampled bilinearly with repeat wrapping (no mipmaps).
#pragma once
#include <array>
#include <cstddef>
#include <string>
#include <vector>

namespace ropsim {

struct Texture {
  std::string name;
  int width = 0, height = 0;
  std::vector<float> rgba;  ///< row 0 = the image's top row; rgb linear, alpha as stored

  /// Bilinear, repeat wrap; (u, v) with v = 0 at the image's bottom (the
  /// OpenGL / assimp convention), texel centres at (i + 1/2) / width.
  std::array<float, 4> sample(double u, double v) const;
};

/// Reads an image file; `srgb` converts colour channels from sRGB to linear.
/// Throws CaptureError naming the file.
Texture load_texture_file(const std::string& path, bool srgb = true);
/// Decodes an image held in memory (`hint`: file extension such as "png").
Texture load_texture_memory(const void* data, size_t bytes, const std::string& hint, const std::string& name,
                            bool srgb = true);

}  // namespace ropsim
