#include "traces/glcapture/fragment_order.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <memory>
#include <thread>
#include <tuple>

#include "traces/glcapture/glsl_rewrite.h"

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
                            const std::vector<DrawPart>& parts, bool clamp, std::vector<CapturedFragment>& out,
                            uint32_t width, uint32_t height) {
  // The work is split over threads by records, then by pixels; each split's
  // result is merged in a fixed order, so the fragments do not depend on the
  // thread count.
  const size_t nthreads =
      records.size() < (size_t(1) << 20) ? 1 : std::max<size_t>(1, std::min(8u, std::thread::hardware_concurrency()));
  auto in_parallel = [nthreads](const std::function<void(size_t)>& work) {
    std::vector<std::thread> threads;
    for (size_t t = 1; t < nthreads; ++t) threads.emplace_back(work, t);
    work(0);
    for (std::thread& th : threads) th.join();
  };
  auto slice = [](size_t n, size_t t, size_t parts_) { return std::make_pair(n * t / parts_, n * (t + 1) / parts_); };

  if (width == 0 || height == 0) {  // the pixels' extent from the records
    width = height = 0;
    for (const PassRecord& r : records) {
      width = std::max<uint32_t>(width, uint32_t(r.x) + 1);
      height = std::max<uint32_t>(height, uint32_t(r.y) + 1);
    }
  }
  // The buckets: every pixel of the target; or, when the records are few
  // for its area (a large target), only the pixels they hit (sorted ids).
  const bool dense = size_t(width) * height <= 2 * records.size() + (size_t(1) << 20);
  std::vector<uint32_t> hit;
  if (!dense) {
    hit.reserve(records.size());
    for (const PassRecord& r : records)
      if (r.x < width && r.y < height) hit.push_back(uint32_t(r.y) * width + r.x);
    std::sort(hit.begin(), hit.end());
    hit.erase(std::unique(hit.begin(), hit.end()), hit.end());
  }
  const size_t pixels = dense ? size_t(width) * height : hit.size();
  auto bucket = [&](const PassRecord& r) -> size_t {
    const uint32_t id = uint32_t(r.y) * width + r.x;
    return dense ? id : size_t(std::lower_bound(hit.begin(), hit.end(), id) - hit.begin());
  };

  // Primitive numbering: each part's primitives per instance (the call's
  // count, or more when the records show more) and its instances; in the
  // same scan, each thread's count of records in each pixel.
  struct Extent {
    bool outside = false;
    std::vector<uint64_t> per_instance, instances;
  };
  std::vector<Extent> ext(nthreads);
  std::vector<std::vector<uint32_t>> next(nthreads);  // then each thread's next slot in each pixel's bucket
  in_parallel([&](size_t t) {
    Extent& e = ext[t];
    std::vector<uint32_t>& n = next[t];
    n.assign(pixels, 0);
    const auto [lo, hi] = slice(records.size(), t, nthreads);
    for (size_t i = lo; i < hi; ++i) {
      const PassRecord& r = records[i];
      if (r.part >= e.per_instance.size()) {
        e.per_instance.resize(size_t(r.part) + 1, 0);
        e.instances.resize(size_t(r.part) + 1, 0);
      }
      e.per_instance[r.part] = std::max<uint64_t>(e.per_instance[r.part], uint64_t(r.prim) + 1);
      e.instances[r.part] = std::max<uint64_t>(e.instances[r.part], uint64_t(r.instance) + 1);
      if (r.x >= width || r.y >= height) {
        e.outside = true;
        continue;
      }
      ++n[bucket(r)];
    }
  });
  std::vector<uint64_t> per_instance(parts.size(), 0), instances(parts.size(), 0);
  for (size_t k = 0; k < parts.size(); ++k) per_instance[k] = parts[k].prims_per_instance;
  for (const Extent& e : ext) {
    if (e.outside)
      return "draw " + std::to_string(draw_id) + " has a record outside the " + std::to_string(width) + "x" +
             std::to_string(height) + " target";
    if (e.per_instance.size() > per_instance.size()) {
      per_instance.resize(e.per_instance.size(), 0);
      instances.resize(e.per_instance.size(), 0);
    }
    for (size_t k = 0; k < e.per_instance.size(); ++k) {
      per_instance[k] = std::max(per_instance[k], e.per_instance[k]);
      instances[k] = std::max(instances[k], e.instances[k]);
    }
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
  std::vector<uint32_t> start(pixels + 1, 0);
  for (size_t p = 0; p < pixels; ++p) {
    uint32_t at = start[p];
    for (size_t t = 0; t < nthreads; ++t) {
      const uint32_t c = next[t][p];
      next[t][p] = at;
      at += c;
    }
    start[p + 1] = at;
  }
  const std::unique_ptr<Key[]> keys(new Key[records.size()]);  // no zeroing: every key is written
  in_parallel([&](size_t t) {
    std::vector<uint32_t>& at = next[t];
    const auto [lo, hi] = slice(records.size(), t, nthreads);
    for (size_t i = lo; i < hi; ++i) {
      const PassRecord& r = records[i];
      const uint64_t prim = base[r.part] + uint64_t(r.instance) * per_instance[r.part] + r.prim;
      keys[at[bucket(r)]++] = Key{prim << 8 | r.sample, bits(r.z), uint32_t(i)};
    }
  });
  next.clear();
  next.shrink_to_fit();
  auto less = [&records](const Key& a, const Key& b) {
    if (a.prim_sample != b.prim_sample) return a.prim_sample < b.prim_sample;
    if (a.z != b.z) return a.z < b.z;
    const auto& ca = records[a.index].rgba;
    const auto& cb = records[b.index].rgba;
    for (size_t c = 0; c < 4; ++c)
      if (bits(ca[c]) != bits(cb[c])) return bits(ca[c]) < bits(cb[c]);
    return false;
  };

  // Each pixel's fragments, pixel by pixel (a thread a range of pixels);
  // then all of them into API order by (prim_id, row, column), one
  // fragment a (prim_id, pixel).
  struct Made {
    uint64_t order;  ///< prim_id << 32 | row << 16 | column
    uint32_t index;  ///< in its thread's made, then in all of them
  };
  std::vector<std::vector<CapturedFragment>> made(nthreads);
  std::vector<std::vector<Made>> made_order(nthreads);
  in_parallel([&](size_t t) {
    const auto [plo, phi] = slice(pixels, t, nthreads);
    for (size_t p = plo; p < phi; ++p) {
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
      const uint32_t id = dense ? uint32_t(p) : hit[p];
      const uint16_t x = uint16_t(id % width), y = uint16_t(id / width);
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
          made_order[t].push_back(Made{prim << 32 | uint64_t(y) << 16 | x, uint32_t(made[t].size())});
          made[t].push_back(std::move(f));
        }
        i = j;
      }
    }
  });
  std::vector<Made> order;
  std::vector<CapturedFragment*> fragment;
  for (size_t t = 0; t < nthreads; ++t) {
    for (Made m : made_order[t]) order.push_back(Made{m.order, uint32_t(fragment.size() + m.index)});
    for (CapturedFragment& f : made[t]) fragment.push_back(&f);
  }
  made_order.clear();
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
  for (const Made& m : order) out.push_back(std::move(*fragment[m.index]));
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
