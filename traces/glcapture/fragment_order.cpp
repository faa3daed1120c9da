#include "fragment_order.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <tuple>

#include "glsl_rewrite.h"

namespace ropsim::glcapture {

namespace {

uint32_t bits(float f) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}

float word_float(uint32_t u) {
  float f;
  std::memcpy(&f, &u, 4);
  return f;
}

float clamp_unit(float v) { return std::isnan(v) ? 0.0f : std::min(1.0f, std::max(0.0f, v)); }
float clamp_non_negative(float v) {
  if (std::isnan(v)) return 0.0f;
  return std::isinf(v) && v > 0 ? 0.0f : std::max(0.0f, v);
}

}  // namespace

std::array<float, 2> sample_clip_offset(SamplePos p, int viewport_w, int viewport_h) {
  // The sample's offset from the pixel centre in GL window units (y up).
  const double dx = double(p.x) / 256.0 - 0.5;
  const double dy = 0.5 - double(p.y) / 256.0;
  // Window units -> normalised device coordinates: 2 / the viewport's side.
  return {float(-2.0 * dx / double(viewport_w)), float(-2.0 * dy / double(viewport_h))};
}

bool needs_centre_pass(const std::array<SamplePos, 64>& positions, int spp) {
  for (int i = 0; i < spp; ++i)
    if (positions[size_t(i)].x == 128 && positions[size_t(i)].y == 128) return false;
  return true;
}

std::string decode_records(const uint32_t* raw, size_t count, uint32_t width, uint32_t height, uint32_t part,
                           int sample, std::vector<PassRecord>& out) {
  if (out.capacity() < out.size() + count) out.reserve(std::max(out.size() + count, 2 * out.capacity()));
  for (size_t i = 0; i < count; ++i) {
    const uint32_t* w = raw + i * kRecordWords;
    const uint32_t x = w[0] & 0xFFFF, gy = w[0] >> 16;
    if (x >= width || gy >= height)
      return "a fragment at (" + std::to_string(x) + ", " + std::to_string(gy) + ") is outside the " +
             std::to_string(width) + "x" + std::to_string(height) + " target";
    PassRecord r;
    r.x = uint16_t(x);
    r.y = uint16_t(height - 1 - gy);
    r.prim = w[1];
    r.instance = w[2];
    r.part = part;
    r.sample = uint8_t(sample);
    r.z = word_float(w[3]);
    if (!(r.z >= 0.0f && r.z <= 1.0f)) return "a fragment's depth " + std::to_string(r.z) + " is not in [0, 1]";
    for (int c = 0; c < 4; ++c) r.rgba[size_t(c)] = word_float(w[4 + c]);
    out.push_back(r);
  }
  return "";
}

std::string build_fragments(const std::vector<PassRecord>& records, uint32_t draw_id,
                            const std::vector<DrawPart>& parts, bool clamp, std::vector<CapturedFragment>& out) {
  // Primitive numbering: each part's primitives per instance (the call's
  // count, or more when the records show more) and its instances.
  uint32_t nparts = 0;
  for (const PassRecord& r : records) nparts = std::max(nparts, r.part + 1);
  std::vector<uint64_t> per_instance(std::max<size_t>(nparts, parts.size()), 0), instances(per_instance.size(), 0);
  for (size_t k = 0; k < parts.size(); ++k) per_instance[k] = parts[k].prims_per_instance;
  for (const PassRecord& r : records) {
    per_instance[r.part] = std::max<uint64_t>(per_instance[r.part], uint64_t(r.prim) + 1);
    instances[r.part] = std::max<uint64_t>(instances[r.part], uint64_t(r.instance) + 1);
  }
  std::vector<uint64_t> base(per_instance.size() + 1, 0);
  for (size_t k = 0; k < per_instance.size(); ++k) base[k + 1] = base[k] + per_instance[k] * instances[k];
  if (base.back() > UINT32_MAX)
    return "draw " + std::to_string(draw_id) + " has " + std::to_string(base.back()) +
           " primitives, more than a trace's 32-bit primitive id numbers";

  // Sort keys: (prim_id, row, column), then (sample, depth bits), then the
  // colour's bits: a full order, so that equal keys from any thread
  // interleaving sort alike.
  struct Key {
    uint64_t pixel, sample_z;
    uint32_t index;
  };
  std::vector<Key> keys(records.size());
  for (size_t i = 0; i < records.size(); ++i) {
    const PassRecord& r = records[i];
    const uint64_t prim = base[r.part] + uint64_t(r.instance) * per_instance[r.part] + r.prim;
    keys[i] = Key{prim << 32 | uint64_t(r.y) << 16 | r.x, uint64_t(r.sample) << 32 | bits(r.z), uint32_t(i)};
  }
  // By pixel key: a stable least-significant-digit radix sort (a byte a
  // pass, the bytes every key shares skipped); then each pixel's few
  // records by (sample, depth, colour).
  {
    std::vector<Key> tmp(keys.size());
    for (int shift = 0; shift < 64; shift += 8) {
      size_t count[257] = {};
      for (const Key& k : keys) ++count[((k.pixel >> shift) & 0xFF) + 1];
      if (std::any_of(count + 1, count + 257, [&](size_t c) { return c == keys.size(); })) continue;
      for (int b = 0; b < 256; ++b) count[b + 1] += count[b];
      for (const Key& k : keys) tmp[count[(k.pixel >> shift) & 0xFF]++] = k;
      keys.swap(tmp);
    }
  }
  auto within_pixel = [&records](const Key& a, const Key& b) {
    if (a.sample_z != b.sample_z) return a.sample_z < b.sample_z;
    const auto& ca = records[a.index].rgba;
    const auto& cb = records[b.index].rgba;
    for (size_t c = 0; c < 4; ++c)
      if (bits(ca[c]) != bits(cb[c])) return bits(ca[c]) < bits(cb[c]);
    return false;
  };
  for (size_t i = 0; i < keys.size();) {
    size_t j = i + 1;
    while (j < keys.size() && keys[j].pixel == keys[i].pixel) ++j;
    if (j - i > 1) std::sort(keys.begin() + long(i), keys.begin() + long(j), within_pixel);
    i = j;
  }

  for (size_t i = 0; i < keys.size();) {
    size_t j = i;
    CapturedFragment f;
    f.draw_id = draw_id;
    const PassRecord *centre = nullptr, *lowest = nullptr;
    for (; j < keys.size() && keys[j].pixel == keys[i].pixel; ++j) {
      const PassRecord& r = records[keys[j].index];
      if (r.sample == kCentrePass) {
        if (!centre) centre = &r;  // a repeat: the smallest depth came first
        continue;
      }
      const uint64_t bit = uint64_t(1) << r.sample;
      if (f.coverage & bit) continue;
      if (!lowest) lowest = &r;
      f.coverage |= bit;
      f.z.push_back(r.z);
    }
    if (f.coverage != 0) {
      const PassRecord* colour = centre ? centre : lowest;
      f.prim_id = uint32_t(keys[i].pixel >> 32);
      f.x = colour->x;
      f.y = colour->y;
      for (size_t c = 0; c < 4; ++c)
        f.rgba[c] = clamp || c == 3 ? clamp_unit(colour->rgba[c]) : clamp_non_negative(colour->rgba[c]);
      out.push_back(std::move(f));
    }
    i = j;
  }
  return "";
}

Fragment to_trace_fragment(const CapturedFragment& c) {
  Fragment f;
  f.draw_id = c.draw_id;
  f.prim_id = c.prim_id;
  f.x = c.x;
  f.y = c.y;
  f.coverage = c.coverage;
  size_t k = 0;
  for (uint64_t m = c.coverage; m; m &= m - 1) f.z[size_t(__builtin_ctzll(m))] = c.z[k++];
  f.rgb = {c.rgba[0], c.rgba[1], c.rgba[2]};
  f.alpha = c.rgba[3];
  return f;
}

}  // namespace ropsim::glcapture
