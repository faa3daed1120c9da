#include "rtl_models/functional/surface_bytes.h"

#include <cstring>

#include "rtl_models/algo/half.h"
#include "rtl_models/algo/numerics.h"
#include "rtl_models/functional/framebuffer_blend.h"
#include "util/errors.h"

namespace ropsim {

SurfaceBytes surface_bytes(const TraceHeader& h, const StoreTargets& t) {
  SurfaceBytes s;
  s.encoding = frame_encoding(h.draws);
  const bool rgba8 = s.encoding != TargetEncoding::kFloat;
  s.host = plain_sample_bytes(t.formats);
  s.stored = s.host;
  if (rgba8) {
    s.stored[size_t(Buffer::kColor)] = kRgba8SampleBytes;
    if (t.framebuffer) s.stored[size_t(Buffer::kAccum)] = kRgba8SampleBytes;
  }
  return s;
}

void SurfaceBytes::store(Buffer b, const uint8_t* host_bytes, size_t n, uint8_t* out) const {
  // Every stored value of an 8-bit target is one of its 256 codes per
  // channel (framebuffer_store), so the code is exact: the colour buffer's
  // working value stored back in the encoding, the framebuffer's stored value.
  if (b == Buffer::kColor) {
    for (size_t i = 0; i < n; ++i) {
      uint16_t rgb[3];
      std::memcpy(rgb, host_bytes + i * kColorSampleBytes, sizeof rgb);
      for (int c = 0; c < 3; ++c)
        out[4 * i + size_t(c)] = uint8_t(fb::code_of(framebuffer_store(encoding, c, half_to_float(rgb[c]))));
      out[4 * i + 3] = 255;  // destination alpha is not kept: it reads as 1
    }
    return;
  }
  invariant(b == Buffer::kAccum && converts(b), "only the colour buffer and blend's framebuffer are converted");
  const uint32_t hb = host[size_t(b)];  // RGBA binary32 (target_formats)
  for (size_t i = 0; i < n; ++i) {
    float rgba[4];
    std::memcpy(rgba, host_bytes + i * hb, sizeof rgba);
    for (int c = 0; c < 4; ++c) out[4 * i + size_t(c)] = uint8_t(fb::code_of(rgba[c]));
  }
}

}  // namespace ropsim
