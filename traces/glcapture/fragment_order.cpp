#include "fragment_order.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
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
  uint32_t width = 0, height = 0;
  std::vector<uint64_t> per_instance(parts.size(), 0), instances(parts.size(), 0);
  for (size_t k = 0; k < parts.size(); ++k) per_instance[k] = parts[k].prims_per_instance;
  for (const PassRecord& r : records) {
    if (r.part >= per_instance.size()) {
      per_instance.resize(size_t(r.part) + 1, 0);
      instances.resize(size_t(r.part) + 1, 0);
    }
    per_instance[r.part] = std::max<uint64_t>(per_instance[r.part], uint64_t(r.prim) + 1);
    instances[r.part] = std::max<uint64_t>(instances[r.part], uint64_t(r.instance) + 1);
    width = std::max<uint32_t>(width, uint32_t(r.x) + 1);
    height = std::max<uint32_t>(height, uint32_t(r.y) + 1);
  }
  std::vector<uint64_t> base(per_instance.size() + 1, 0);
  for (size_t k = 0; k < per_instance.size(); ++k) base[k + 1] = base[k] + per_instance[k] * instances[k];
  if (base.back() > UINT32_MAX)
    return "draw " + std::to_string(draw_id) + " has " + std::to_string(base.back()) +
           " primitives, more than a trace's 32-bit primitive id numbers";
  if (records.empty()) return "";
  if (records.size() > UINT32_MAX)
    return "draw " + std::to_string(draw_id) + " has " + std::to_string(records.size()) +
           " pass records, more than 32-bit indices number";

  // The records bucketed by pixel (a counting sort on row * width + column,
  // stable), each a 16-byte key: (prim_id, sample), the depth's bits and
  // the record's index. Within a pixel the keys then sort by (prim_id,
  // sample, depth bits, colour bits): a full order, so that equal keys from
  // any thread interleaving sort alike.
  struct Key {
    uint64_t prim_sample;
    uint32_t z, index;
  };
  const size_t pixels = size_t(width) * height;
  std::vector<uint32_t> start(pixels + 1, 0);
  for (const PassRecord& r : records) ++start[size_t(r.y) * width + r.x + 1];
  for (size_t p = 0; p < pixels; ++p) start[p + 1] += start[p];
  const std::unique_ptr<Key[]> keys(new Key[records.size()]);  // no zeroing: every key is written
  {
    std::vector<uint32_t> next(start.begin(), start.end() - 1);
    for (size_t i = 0; i < records.size(); ++i) {
      const PassRecord& r = records[i];
      const uint64_t prim = base[r.part] + uint64_t(r.instance) * per_instance[r.part] + r.prim;
      keys[next[size_t(r.y) * width + r.x]++] = Key{prim << 8 | r.sample, bits(r.z), uint32_t(i)};
    }
  }
  auto less = [&records](const Key& a, const Key& b) {
    if (a.prim_sample != b.prim_sample) return a.prim_sample < b.prim_sample;
    if (a.z != b.z) return a.z < b.z;
    const auto& ca = records[a.index].rgba;
    const auto& cb = records[b.index].rgba;
    for (size_t c = 0; c < 4; ++c)
      if (bits(ca[c]) != bits(cb[c])) return bits(ca[c]) < bits(cb[c]);
    return false;
  };

  // Each pixel's fragments, pixel by pixel; then all of them into API
  // order by (prim_id, row, column), one fragment a (prim_id, pixel).
  struct Made {
    uint64_t order;  ///< prim_id << 32 | row << 16 | column
    uint32_t index;  ///< in made
  };
  std::vector<CapturedFragment> made;
  std::vector<Made> order;
  for (size_t p = 0; p < pixels; ++p) {
    Key* const first = keys.get() + start[p];
    Key* const last = keys.get() + start[p + 1];
    if (first == last) continue;
    if (last - first > 48) {
      std::sort(first, last, less);
    } else if (last - first > 1) {
      // Insertion sort: a pixel mostly has a few records.
      for (Key* k = first + 1; k < last; ++k) {
        const Key v = *k;
        Key* j = k;
        for (; j > first && less(v, j[-1]); --j) *j = j[-1];
        *j = v;
      }
    }
    const uint16_t x = uint16_t(p % width), y = uint16_t(p / width);
    for (Key* i = first; i < last;) {
      const uint64_t prim = i->prim_sample >> 8;
      uint64_t coverage = 0;
      uint32_t centre = UINT32_MAX, lowest = UINT32_MAX;
      float z[64];
      int covered = 0;
      Key* j = i;
      for (; j < last && j->prim_sample >> 8 == prim; ++j) {
        const unsigned sample = unsigned(j->prim_sample & 0xFF);
        if (sample == kCentrePass) {
          if (centre == UINT32_MAX) centre = j->index;  // a repeat: the smallest depth came first
          continue;
        }
        const uint64_t bit = uint64_t(1) << sample;
        if (coverage & bit) continue;
        if (lowest == UINT32_MAX) lowest = j->index;
        coverage |= bit;
        z[covered++] = word_float(j->z);
      }
      if (coverage != 0) {
        CapturedFragment f;
        f.draw_id = draw_id;
        f.prim_id = uint32_t(prim);
        f.x = x;
        f.y = y;
        f.coverage = coverage;
        f.z.assign(z, z + covered);
        const PassRecord& colour = records[centre != UINT32_MAX ? centre : lowest];
        for (size_t c = 0; c < 4; ++c)
          f.rgba[c] = clamp || c == 3 ? clamp_unit(colour.rgba[c]) : clamp_non_negative(colour.rgba[c]);
        order.push_back(Made{prim << 32 | uint64_t(y) << 16 | x, uint32_t(made.size())});
        made.push_back(std::move(f));
      }
      i = j;
    }
  }
  // A stable least-significant-digit radix sort of the (unique) order keys:
  // a byte a pass, the bytes every key shares skipped.
  {
    std::vector<Made> tmp(order.size());
    for (int shift = 0; shift < 64; shift += 8) {
      size_t count[257] = {};
      for (const Made& m : order) ++count[((m.order >> shift) & 0xFF) + 1];
      if (std::any_of(count + 1, count + 257, [&](size_t c) { return c == order.size(); })) continue;
      for (int b = 0; b < 256; ++b) count[b + 1] += count[b];
      for (const Made& m : order) tmp[count[(m.order >> shift) & 0xFF]++] = m;
      order.swap(tmp);
    }
  }
  out.reserve(out.size() + order.size());
  for (const Made& m : order) out.push_back(std::move(made[m.index]));
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
