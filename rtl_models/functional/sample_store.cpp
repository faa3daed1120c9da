#include "rtl_models/functional/sample_store.h"

#include <cstring>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "rtl_models/algo/compression.h"
#include "rtl_models/algo/depth.h"
#include "rtl_models/algo/half.h"
#include "rtl_models/algo/numerics.h"
#include "rtl_models/functional/framebuffer_blend.h"
#include "util/errors.h"

namespace ropsim {

SampleStore::SampleStore(const TraceHeader& h, bool with_tracker, const StoreTargets& targets)
    : header_(h),
      with_tracker_(with_tracker),
      slab_bits_(targets.slab_bits),
      targets_(targets),
      tiles_(h.width, h.height),
      clear_depth_(canonical_depth(h.clear_depth)) {
  const std::array<float, 3> clear = colour_buffer_clear(frame_encoding(h.draws), h.clear_color);
  for (int c = 0; c < 3; ++c) clear_rgb16_[c] = float_to_half(clear[size_t(c)]);
  // The block: the header, then each buffer from a cache line.
  const size_t n = size_t(64) * size_t(h.spp);
  size_t at = sizeof(SampleTile);
  auto place = [&at](size_t bytes) {
    const size_t here = (at + 63) / 64 * 64;
    at = here + bytes;
    return here;
  };
  layout_.depth = place(n * sizeof(float));
  layout_.rgb = place(3 * n * sizeof(uint16_t));
  if (with_tracker_) layout_.tracker = place(64 * sizeof(TrackerState));
  if (slab_bits_ > 0) layout_.slab = place(64 * sizeof(SlabPixel));
  if (targets_.transmittance) layout_.trans = place(n * sample_bytes(targets_.formats.transmittance));
  if (targets_.accum) layout_.accum = place(n * sample_bytes(targets_.formats.accum));
  if (targets_.planes) layout_.plane = place(n * sizeof(uint64_t));
  layout_.bytes = (at + 63) / 64 * 64;
  mem_.add(tiles_.directory_bytes(), "the tile directory of the screen");
}

std::unique_ptr<SampleTile> SampleTile::make(const SampleTileLayout& l) {
  void* block = ::operator new (l.bytes, std::align_val_t{alignof(SampleTile)});
  std::unique_ptr<SampleTile> t(new (block) SampleTile);
  uint8_t* b = t->base();
  t->depth = reinterpret_cast<float*>(b + l.depth);
  t->rgb = reinterpret_cast<uint16_t*>(b + l.rgb);
  t->tracker = l.tracker ? reinterpret_cast<TrackerState*>(b + l.tracker) : nullptr;
  t->slab = l.slab ? reinterpret_cast<SlabPixel*>(b + l.slab) : nullptr;
  t->trans = l.trans ? b + l.trans : nullptr;
  t->accum = l.accum ? b + l.accum : nullptr;
  t->plane = l.plane ? reinterpret_cast<uint64_t*>(b + l.plane) : nullptr;
  return t;
}

PixelRef SampleStore::pixel(uint32_t x, uint32_t y) {
  const int spp = header_.spp;
  SampleTile& t = tiles_.get(x, y, [&](uint32_t, uint32_t) {
    mem_.add(layout_.bytes, "the per-sample buffers of the touched tiles");
    auto tile = SampleTile::make(layout_);
    const size_t n = size_t(64) * spp;
    std::fill_n(tile->depth, n, clear_depth_);
    for (size_t i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) tile->rgb[3 * i + c] = clear_rgb16_[c];
    if (tile->tracker) std::uninitialized_value_construct_n(tile->tracker, 64);
    if (tile->slab) std::uninitialized_value_construct_n(tile->slab, 64);
    if (tile->plane) std::fill_n(tile->plane, n, kClearPlaneKey);
    // The clear value encoded once, then copied to every sample.
    auto clear_target = [n](uint8_t* buf, TargetFormat f, const float* v) {
      const uint32_t b = sample_bytes(f);
      uint8_t one[16];
      for (int c = 0; c < channels(f); ++c) target_store(f, one, c, v[c]);
      for (size_t i = 0; i < n; ++i) std::memcpy(buf + i * b, one, b);
    };
    const float one = 1.0f;
    if (tile->trans) clear_target(tile->trans, targets_.formats.transmittance, &one);
    if (tile->accum) clear_target(tile->accum, targets_.formats.accum, targets_.accum_clear.data());
    return tile;
  });
  return in_tile(t.base(), x, y);
}

PixelRef SampleStore::in_tile(const uint8_t* cb, uint32_t x, uint32_t y) const {
  // From the tile's address and the layout: no load of the tile's header.
  uint8_t* b = const_cast<uint8_t*>(cb);
  const int p = pixel_in_tile(x, y);
  const size_t ps = size_t(p) * size_t(header_.spp);
  const SampleTileLayout& l = layout_;
  return PixelRef{reinterpret_cast<float*>(b + l.depth) + ps,
                  reinterpret_cast<uint16_t*>(b + l.rgb) + ps * 3,
                  l.tracker ? reinterpret_cast<TrackerState*>(b + l.tracker) + p : nullptr,
                  l.slab ? reinterpret_cast<SlabPixel*>(b + l.slab) + p : nullptr,
                  l.trans ? b + l.trans + ps * sample_bytes(targets_.formats.transmittance) : nullptr,
                  l.accum ? b + l.accum + ps * sample_bytes(targets_.formats.accum) : nullptr,
                  l.plane ? reinterpret_cast<uint64_t*>(b + l.plane) + ps : nullptr};
}

void SampleStore::absorb(SampleStore& o) {
  if (o.header_.width != header_.width || o.header_.height != header_.height || o.header_.spp != header_.spp ||
      o.with_tracker_ != with_tracker_ || o.slab_bits_ != slab_bits_ ||
      o.targets_.transmittance != targets_.transmittance || o.targets_.accum != targets_.accum ||
      o.targets_.planes != targets_.planes)
    throw InternalError("SampleStore::absorb: the stores hold different buffers");
  if (!tiles_.absorb(o.tiles_)) throw InternalError("SampleStore::absorb: a tile held by both stores");
  mem_.take(o.mem_);  // its tiles' bytes (and its directory's, until it is freed)
}

void SampleStore::copy_tile_from(const SampleStore& src, uint32_t x, uint32_t y) {
  if (src.header_.width != header_.width || src.header_.height != header_.height || src.header_.spp != header_.spp ||
      src.with_tracker_ != with_tracker_ || src.slab_bits_ != slab_bits_ ||
      src.targets_.transmittance != targets_.transmittance || src.targets_.accum != targets_.accum ||
      src.targets_.planes != targets_.planes)
    throw InternalError("SampleStore::copy_tile_from: the stores hold different buffers");
  const SampleTile* from = src.tiles_.find(x, y);
  if (!from) return;
  const uint32_t x0 = x & ~7u, y0 = y & ~7u;
  pixel(x0, y0);  // allocates the tile
  SampleTile& to = *tiles_.find(x0, y0);
  const size_t n = size_t(64) * header_.spp;
  std::memcpy(to.depth, from->depth, n * sizeof(float));
  std::memcpy(to.rgb, from->rgb, 3 * n * sizeof(uint16_t));
  if (to.tracker) std::copy_n(from->tracker, 64, to.tracker);
  if (to.slab) std::copy_n(from->slab, 64, to.slab);
  if (to.trans) std::memcpy(to.trans, from->trans, n * sample_bytes(targets_.formats.transmittance));
  if (to.accum) std::memcpy(to.accum, from->accum, n * sample_bytes(targets_.formats.accum));
  if (to.plane) std::copy_n(from->plane, n, to.plane);
}

void SampleStore::copy_pixel_from(const SampleStore& src, uint32_t x, uint32_t y) {
  if (src.header_.width != header_.width || src.header_.height != header_.height || src.header_.spp != header_.spp ||
      src.with_tracker_ != with_tracker_ || src.slab_bits_ != slab_bits_ ||
      src.targets_.transmittance != targets_.transmittance || src.targets_.accum != targets_.accum ||
      src.targets_.planes != targets_.planes)
    throw InternalError("SampleStore::copy_pixel_from: the stores hold different buffers");
  const PixelRef to = pixel(x, y);
  const PixelView from = src.view(x, y);
  if (!from.depth) return;
  const size_t n = size_t(header_.spp);
  std::memcpy(to.depth, from.depth, n * sizeof(float));
  std::memcpy(to.rgb, from.rgb, 3 * n * sizeof(uint16_t));
  if (to.tracker) *to.tracker = *from.tracker;
  if (to.slab) *to.slab = *from.slab;
  if (to.trans) std::memcpy(to.trans, from.trans, n * sample_bytes(targets_.formats.transmittance));
  if (to.accum) std::memcpy(to.accum, from.accum, n * sample_bytes(targets_.formats.accum));
  if (to.plane) std::copy_n(from.plane, n, to.plane);
}

PixelView SampleStore::view(uint32_t x, uint32_t y) const {
  const SampleTile* t = tiles_.find(x, y);
  if (!t) return {};
  const PixelRef r = in_tile(t->base(), x, y);
  return PixelView{r.depth, r.rgb, r.tracker, r.slab, r.trans, r.accum, r.plane};
}

Image SampleStore::resolve(bool background_per_sample) const {
  const float clear[3] = {half_to_float(clear_rgb16_[0]), half_to_float(clear_rgb16_[1]),
                          half_to_float(clear_rgb16_[2])};
  // Untouched tiles stay the clear colour and take no memory.
  Image img(header_.width, header_.height, {clear[0], clear[1], clear[2]});
  const int spp = header_.spp;
  const float inv = 1.0f / float(spp);  // exact: spp is a power of two
  const std::array<uint64_t, 64> bits_of =
      slab_bits_ > 0 && background_per_sample ? slab_sample_bits(spp, slab_bits_) : std::array<uint64_t, 64>{};
  tiles_.for_each([&](uint32_t x0, uint32_t y0, const SampleTile& t) {
    for (int p = 0; p < 64; ++p) {
      const uint32_t x = x0 + (p & 7), y = y0 + (p >> 3);
      if (x >= img.width || y >= img.height) continue;
      const uint16_t* c = t.rgb + size_t(p) * spp * 3;
      float sum[3] = {0, 0, 0};
      for (int s = 0; s < spp; ++s)  // summed in sample order: deterministic
        for (int ch = 0; ch < 3; ++ch) sum[ch] += half_to_float(c[3 * s + ch]);
      float* o = img.at(x, y);
      if (t.slab) {  // slab: its layers, front to back (the samples are unused)
        const SlabPixel& sp = t.slab[size_t(p)];
        float rgb[kMaxSlabLayers][3];
        for (int l = 0; l < sp.count; ++l)
          for (int ch = 0; ch < 3; ++ch) rgb[l][ch] = half_to_float(sp.rgb[l][ch]);
        if (background_per_sample) {
          float bg[64 * 3];
          for (int k = 0; k < 3 * spp; ++k) bg[k] = half_to_float(c[k]);
          slab_resolve_over(sp, slab_bits_, rgb, bits_of.data(), spp, bg, o);
        } else {
          slab_resolve(sp, slab_bits_, rgb, clear, o);
        }
        continue;
      }
      for (int ch = 0; ch < 3; ++ch) o[ch] = sum[ch] * inv;
    }
  });
  return img;
}

size_t SampleStore::tile_bytes() const {
  return size_t(64) * header_.spp * (kDepthSampleBytes + kColorSampleBytes) +
         (with_tracker_ ? 64 * sizeof(TrackerState) : 0) + (slab_bits_ > 0 ? 64 * sizeof(SlabPixel) : 0) +
         size_t(64) * header_.spp *
             ((targets_.transmittance ? sample_bytes(targets_.formats.transmittance) : 0) +
              (targets_.accum ? sample_bytes(targets_.formats.accum) : 0) + (targets_.planes ? sizeof(uint64_t) : 0));
}

size_t SampleStore::state_bytes() const { return tiles_.tiles() * tile_bytes() + tiles_.directory_bytes(); }

std::string first_state_difference(const SampleStore& a, const SampleStore& b) {
  const TraceHeader& h = a.header();
  if (h.width != b.header().width || h.height != b.header().height || h.spp != b.header().spp)
    return "the stores have different screen sizes or spp";
  if (a.has_tracker() != b.has_tracker()) return "one store tracks surfaces, the other does not";
  if (a.has_slab() != b.has_slab()) return "one store holds SLAB layers, the other does not";
  const StoreTargets &ta_ = a.targets(), &tb_ = b.targets();
  if (ta_.transmittance != tb_.transmittance || ta_.accum != tb_.accum || !(ta_.formats == tb_.formats) ||
      ta_.accum_clear != tb_.accum_clear)
    return "the stores have different render targets";
  const int spp = h.spp;
  const float clear_z = canonical_depth(h.clear_depth);
  uint16_t clear_c[3];
  const std::array<float, 3> clear = colour_buffer_clear(frame_encoding(h.draws), h.clear_color);
  for (int c = 0; c < 3; ++c) clear_c[c] = float_to_half(clear[size_t(c)]);
  std::ostringstream os;
  auto check_tile = [&](uint32_t x0, uint32_t y0) -> bool {
    for (int p = 0; p < 64; ++p) {
      const uint32_t x = x0 + (p & 7), y = y0 + (p >> 3);
      const PixelView va = a.view(x, y), vb = b.view(x, y);
      for (int s = 0; s < spp; ++s) {
        const float za = va.depth ? va.depth[s] : clear_z, zb = vb.depth ? vb.depth[s] : clear_z;
        if (depth_bits(za) != depth_bits(zb)) {
          os << "pixel (" << x << ", " << y << ") sample " << s << ": depth " << za << " vs " << zb;
          return false;
        }
        if (ta_.planes && tb_.planes) {
          const uint64_t ka = va.plane ? va.plane[s] : kClearPlaneKey, kb = vb.plane ? vb.plane[s] : kClearPlaneKey;
          if (ka != kb) {
            os << "pixel (" << x << ", " << y << ") sample " << s << ": depth plane key " << std::hex << ka << " vs "
               << kb << std::dec;
            return false;
          }
        }
        for (int c = 0; c < 3; ++c) {
          const uint16_t ca = va.rgb ? va.rgb[3 * s + c] : clear_c[c], cb = vb.rgb ? vb.rgb[3 * s + c] : clear_c[c];
          if (ca != cb) {
            os << "pixel (" << x << ", " << y << ") sample " << s << " channel " << c << ": colour bits " << ca
               << " vs " << cb;
            return false;
          }
        }
      }
      // Render targets: every byte (an untouched pixel has no bytes to compare
      // unless the other one is touched; the clear values are then compared).
      auto check_target = [&](const char* name, TargetFormat f, const float* clear, const uint8_t* pa,
                              const uint8_t* pb) -> bool {
        const uint32_t bytes = sample_bytes(f);
        std::vector<uint8_t> ca(bytes), cb(bytes);
        for (int c = 0; c < channels(f); ++c) target_store(f, ca.data(), c, clear[c]);
        cb = ca;
        for (int s = 0; s < spp; ++s) {
          const uint8_t* sa = pa ? pa + size_t(s) * bytes : ca.data();
          const uint8_t* sb = pb ? pb + size_t(s) * bytes : cb.data();
          if (std::memcmp(sa, sb, bytes) != 0) {
            os << "pixel (" << x << ", " << y << ") sample " << s << ": " << name << " target bytes differ ("
               << target_load(f, sa, 0) << " vs " << target_load(f, sb, 0) << " in channel 0)";
            return false;
          }
        }
        return true;
      };
      const float one = 1.0f;
      if (ta_.transmittance && !check_target("transmittance", ta_.formats.transmittance, &one, va.trans, vb.trans))
        return false;
      if (ta_.accum && !check_target("accum", ta_.formats.accum, ta_.accum_clear.data(), va.accum, vb.accum))
        return false;
      if (a.has_tracker()) {
        const TrackerState ta = va.tracker ? *va.tracker : TrackerState{},
                           tb = vb.tracker ? *vb.tracker : TrackerState{};
        if (!(ta == tb)) {
          os << "pixel (" << x << ", " << y << "): tracker (id " << ta.surface_id << ", mask " << std::hex << ta.covered
             << std::dec << ") vs (id " << tb.surface_id << ", mask " << std::hex << tb.covered << std::dec << ")";
          return false;
        }
      }
      if (a.has_slab()) {
        const SlabPixel sa = va.slab ? *va.slab : SlabPixel{}, sb = vb.slab ? *vb.slab : SlabPixel{};
        if (!(sa == sb)) {
          os << "pixel (" << x << ", " << y << "): SLAB layers differ (" << int(sa.count) << " vs " << int(sb.count)
             << " layers)";
          return false;
        }
      }
    }
    return true;
  };
  bool same = true;
  a.tile_map().for_each([&](uint32_t x0, uint32_t y0, const SampleTile&) {
    if (same) same = check_tile(x0, y0);
  });
  if (same)
    b.tile_map().for_each([&](uint32_t x0, uint32_t y0, const SampleTile&) {
      if (same) same = check_tile(x0, y0);
    });
  return os.str();
}

}  // namespace ropsim
