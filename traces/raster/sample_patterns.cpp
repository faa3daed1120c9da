#include "traces/raster/sample_patterns.h"

#include <stdexcept>

#include "rtl_models/algo/numerics.h"
#include "util/errors.h"

namespace ropsim {

namespace {
// D3D11 / Vulkan standard sample locations, in 1/16 pixel offsets from the centre.
constexpr int k2[][2] = {{4, 4}, {-4, -4}};
constexpr int k4[][2] = {{-2, -6}, {6, -2}, {-6, 2}, {2, 6}};
constexpr int k8[][2] = {{1, -3}, {-1, 3}, {5, 1}, {-3, -5}, {-5, 5}, {-7, -1}, {3, 7}, {7, -7}};
constexpr int k16[][2] = {{1, 1},  {-1, -3}, {-3, 2},  {4, -1}, {-5, -2}, {2, 5},  {5, 3}, {3, -5},
                          {-2, 6}, {0, -7},  {-4, -6}, {-6, 4}, {-8, 0},  {7, -4}, {6, 7}, {-7, -8}};

template <size_t N>
std::array<SamplePos, 64> from_sixteenths(const int (&p)[N][2]) {
  std::array<SamplePos, 64> out{};
  for (size_t i = 0; i < N; ++i)
    out[i] = SamplePos{static_cast<uint8_t>(128 + 16 * p[i][0]), static_cast<uint8_t>(128 + 16 * p[i][1])};
  return out;
}
}  // namespace

std::array<SamplePos, 64> standard_sample_positions(int spp) {
  switch (spp) {
    case 1:
      return std::array<SamplePos, 64>{};  // all default to the centre (128, 128)
    case 2:
      return from_sixteenths(k2);
    case 4:
      return from_sixteenths(k4);
    case 8:
      return from_sixteenths(k8);
    case 16:
      return from_sixteenths(k16);
    case 32:
    case 64: {
      // Hammersley (0, m, 2)-net: x = (i + 1/2) / N, y = (rev_m(i) + 1/2) / N.
      // Every 1/N-wide column and row holds exactly one sample.
      const int m = log2_floor(unsigned(spp));
      const int cell = 256 / spp;
      std::array<SamplePos, 64> out{};
      for (int i = 0; i < spp; ++i) {
        const int r = int(reverse_low_bits(uint32_t(i), m));
        out[i] = SamplePos{static_cast<uint8_t>(cell * i + cell / 2), static_cast<uint8_t>(cell * r + cell / 2)};
      }
      return out;
    }
    default:
      throw UserError("no standard sample pattern for " + std::to_string(spp) + " spp");
  }
}

}  // namespace ropsim
