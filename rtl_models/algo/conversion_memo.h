// A fragment's opacity in the fixed-point format of the opacity test and its
// colour in binary16, remembered for the next fragment: consecutive fragments
// of one draw usually share both. Used by the golden model and the cycle
// model's units alike.
#pragma once
#include <array>
#include <cstdint>

#include "rtl_models/algo/half.h"
#include "rtl_models/algo/opacity.h"

namespace ropsim {

class ConversionMemo {
 public:
  explicit ConversionMemo(int alpha_bits) : alpha_bits_(alpha_bits) {}
  /// alpha_to_fixed(alpha, alpha_bits).
  uint64_t fixed_alpha(float alpha) {
    if (alpha != alpha_) {
      alpha_ = alpha;
      alpha_fixed_ = alpha_to_fixed(alpha, alpha_bits_);
    }
    return alpha_fixed_;
  }
  /// float_to_half of each channel.
  const uint16_t* half_color(const std::array<float, 3>& rgb) {
    if (rgb != rgb_) {
      rgb_ = rgb;
      for (int c = 0; c < 3; ++c) rgb16_[c] = float_to_half(rgb[c]);
    }
    return rgb16_;
  }

 private:
  int alpha_bits_;
  float alpha_ = -1.0f;  // never a valid opacity
  uint64_t alpha_fixed_ = 0;
  std::array<float, 3> rgb_{-1.0f, -1.0f, -1.0f};  // never a valid colour
  uint16_t rgb16_[3] = {};
};

}  // namespace ropsim
