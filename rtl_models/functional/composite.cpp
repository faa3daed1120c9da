#include "rtl_models/functional/composite.h"

#include <cstring>

#include "rtl_models/algo/depth.h"
#include "rtl_models/algo/half.h"
#include "rtl_models/functional/framebuffer_blend.h"

namespace ropsim {

Image composite(const SampleStore& store, Method m, bool background_per_sample) {
  const TraceHeader& h = store.header();
  const TargetEncoding e = frame_encoding(h.draws);
  const bool e8 = e != TargetEncoding::kFloat;
  const MethodTraits& t = traits(m);
  const BlendFormats& fmt = store.targets().formats;
  const uint32_t tb = sample_bytes(fmt.transmittance), ab = sample_bytes(fmt.accum);
  double bg[3];
  const std::array<float, 3> clear = colour_buffer_clear(e, h.clear_color);
  for (int c = 0; c < 3; ++c) bg[c] = half_to_float(float_to_half(clear[size_t(c)]));  // as the colour buffer holds it
  // Untouched tiles (no memory): the clear colour, as light on an 8-bit target.
  Image img(
      h.width, h.height,
      e8 ? std::array<float, 3>{resolved_light(e, clear[0]), resolved_light(e, clear[1]), resolved_light(e, clear[2])}
         : std::array<float, 3>{float(bg[0]), float(bg[1]), float(bg[2])});
  const int spp = h.spp;
  const uint32_t clear_z = depth_bits(canonical_depth(h.clear_depth));
  const bool in_accum = stochastic_colour_in_accum(m, background_per_sample);
  const bool marked = stochastic_marks_transmittance(m, background_per_sample);
  store.tile_map().for_each([&](uint32_t x0, uint32_t y0, const SampleTile&) {
    for (int p = 0; p < 64; ++p) {
      const uint32_t x = x0 + uint32_t(p & 7), y = y0 + uint32_t(p >> 3);
      if (x >= img.width || y >= img.height) continue;
      const PixelView v = store.view(x, y);
      // Sample s's transmittance, and the background behind it.
      auto transmittance = [&](int s) {
        return v.trans ? target_load(fmt.transmittance, v.trans + size_t(s) * tb, 0) : 1.0;
      };
      auto background = [&](int s, double bs[3]) {
        for (int c = 0; c < 3; ++c) bs[c] = background_per_sample ? double(half_to_float(v.rgb[3 * s + c])) : bg[c];
      };
      // Did the stochastic pass write sample s (method.h: over a pre-pass,
      // +ac's alpha in the accumulation target, +depth's transmittance mark;
      // otherwise a depth that is not the clear depth)? And +ac: its colour.
      auto written_at = [&](int s) {
        if (in_accum) return target_load(fmt.accum, v.accum + size_t(s) * ab, 3) != 0.0;
        if (marked) return transmittance(s) == 0.0;
        return depth_bits(v.depth[s]) != clear_z;
      };
      auto written_colour = [&](int s, int c) {
        return in_accum ? target_load(fmt.accum, v.accum + size_t(s) * ab, c) : double(half_to_float(v.rgb[3 * s + c]));
      };
      // Sums in sample order (deterministic).
      double trans = 0, rgb[3] = {0, 0, 0}, acc[4] = {0, 0, 0, 0}, out[3] = {0, 0, 0}, over[3] = {0, 0, 0};
      double open[3] = {0, 0, 0};  // +depth over a pre-pass: the background of the samples not written
      int written = 0;
      for (int s = 0; s < spp; ++s) {
        const double T = transmittance(s);
        trans += T;
        double bs[3];
        background(s, bs);
        for (int c = 0; c < 3; ++c) over[c] += T * bs[c];
        const bool w = written_at(s);
        written += w;
        if (!w)
          for (int c = 0; c < 3; ++c) open[c] += bs[c];
        if (w && stochastic_writes_color(m))
          for (int c = 0; c < 3; ++c) rgb[c] += written_colour(s, c);
        if (v.accum && !in_accum) {
          const uint8_t* a = v.accum + size_t(s) * ab;
          if (t.wboit) {
            const double wa = wboit_clamp_weight(target_load(fmt.accum, a, 3));
            for (int c = 0; c < 3; ++c) out[c] += target_load(fmt.accum, a, c) / wa * (1.0 - T) + T * bs[c];
          } else {
            for (int c = 0; c < 4; ++c) acc[c] += target_load(fmt.accum, a, c);
          }
        }
      }
      const double S = spp, A = 1.0 - trans / S;
      if (e8) {
        // An 8-bit target: each sample's composite stored as the target
        // stores it and the pixel resolved as blend resolves its framebuffer
        // (as colour_buffer_image): mean_s of these is the formula below.
        float samples[64 * 4], res[3];
        for (int s = 0; s < spp; ++s) {
          const double T = transmittance(s);
          double bs[3];
          background(s, bs);
          const bool w = written_at(s);
          const uint8_t* a = v.accum ? v.accum + size_t(s) * ab : nullptr;
          for (int c = 0; c < 3; ++c) {
            double o;
            if (t.wboit) {
              o = target_load(fmt.accum, a, c) / wboit_clamp_weight(target_load(fmt.accum, a, 3)) * (1.0 - T) +
                  T * bs[c];
            } else if (t.depth_based && t.total_alpha) {
              o = (acc[3] > 0 ? A * acc[c] / acc[3] : 0.0) + T * bs[c];
            } else if (t.depth_based) {
              o = target_load(fmt.accum, a, c) + (w ? 0.0 : bs[c]);
            } else {  // +ac
              o = (written > 0 ? A * rgb[c] / written : 0.0) + T * bs[c];
            }
            samples[4 * s + c] = framebuffer_store(e, c, float(o));
          }
          samples[4 * s + 3] = 1.0f;
        }
        framebuffer_resolve_pixel(e, samples, spp, res);
        float* o = img.at(x, y);
        for (int c = 0; c < 3; ++c) o[c] = framebuffer_light(e, res[c]);
        continue;
      }
      if (t.wboit) {
        for (int c = 0; c < 3; ++c) out[c] /= S;
      } else if (t.depth_based && t.total_alpha) {
        for (int c = 0; c < 3; ++c)
          out[c] = (acc[3] > 0 ? A * acc[c] / acc[3] : 0.0) + (background_per_sample ? over[c] / S : trans / S * bg[c]);
      } else if (t.depth_based) {
        for (int c = 0; c < 3; ++c)
          out[c] = acc[c] / S + (background_per_sample ? open[c] / S : double(spp - written) / S * bg[c]);
      } else {  // +ac
        for (int c = 0; c < 3; ++c)
          out[c] =
              (written > 0 ? A * rgb[c] / written : 0.0) + (background_per_sample ? over[c] / S : trans / S * bg[c]);
      }
      float* o = img.at(x, y);
      for (int c = 0; c < 3; ++c) o[c] = float(out[c]);
    }
  });
  return img;
}

Image colour_buffer_image(const SampleStore& store, TargetEncoding e) {
  const TraceHeader& h = store.header();
  const std::array<float, 3> clear = colour_buffer_clear(e, h.clear_color);
  Image img(h.width, h.height, {resolved_light(e, clear[0]), resolved_light(e, clear[1]), resolved_light(e, clear[2])});
  const int spp = h.spp;
  store.tile_map().for_each([&](uint32_t x0, uint32_t y0, const SampleTile&) {
    for (int p = 0; p < 64; ++p) {
      const uint32_t x = x0 + uint32_t(p & 7), y = y0 + uint32_t(p >> 3);
      if (x >= img.width || y >= img.height) continue;
      const PixelView v = store.view(x, y);
      float samples[64 * 4], rgb[3];
      for (int s = 0; s < spp; ++s) {
        for (int c = 0; c < 3; ++c) samples[4 * s + c] = framebuffer_store(e, c, half_to_float(v.rgb[3 * s + c]));
        samples[4 * s + 3] = 1.0f;
      }
      framebuffer_resolve_pixel(e, samples, spp, rgb);
      float* o = img.at(x, y);
      for (int c = 0; c < 3; ++c) o[c] = framebuffer_light(e, rgb[c]);
    }
  });
  return img;
}

void encode_resolved(Image& img, TargetEncoding e) {
  if (e == TargetEncoding::kFloat) return;
  img.transform([e](float v) { return resolved_light(e, v); });
}

Image framebuffer_image(const SampleStore& store) {
  const TraceHeader& h = store.header();
  const TargetEncoding e = frame_encoding(h.draws);
  const std::array<float, 4>& clear = store.targets().accum_clear;
  Image img(h.width, h.height,
            {framebuffer_light(e, clear[0]), framebuffer_light(e, clear[1]), framebuffer_light(e, clear[2])});
  const int spp = h.spp;
  store.tile_map().for_each([&](uint32_t x0, uint32_t y0, const SampleTile&) {
    for (int p = 0; p < 64; ++p) {
      const uint32_t x = x0 + uint32_t(p & 7), y = y0 + uint32_t(p >> 3);
      if (x >= img.width || y >= img.height) continue;
      const PixelView v = store.view(x, y);
      float samples[64 * 4], rgb[3];
      std::memcpy(samples, v.accum, size_t(spp) * 16);
      framebuffer_resolve_pixel(e, samples, spp, rgb);
      float* o = img.at(x, y);
      for (int c = 0; c < 3; ++c) o[c] = framebuffer_light(e, rgb[c]);
    }
  });
  return img;
}

}  // namespace ropsim
