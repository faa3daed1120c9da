#include "traces/glcapture/fragment_order.h"

#include <sys/mman.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <memory>
#include <new>
#include <thread>
#include <tuple>

#include "traces/glcapture/glsl_rewrite.h"

namespace ropsim::glcapture {

namespace {

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

namespace {

/// Runs work(0 .. nthreads - 1), work(0) on the calling thread.
void in_parallel(size_t nthreads, const std::function<void(size_t)>& work) {
  std::vector<std::thread> threads;
  for (size_t t = 1; t < nthreads; ++t) threads.emplace_back(work, t);
  work(0);
  for (std::thread& th : threads) th.join();
}

/// Part t of k of [0, count).
std::pair<size_t, size_t> slice(size_t count, size_t t, size_t k) {
  return std::make_pair(count * t / k, count * (t + 1) / k);
}

/// A draw's fragments in API order (their keys and nodes: scratch.order's
/// first `count`), and each node's coverage (scratch.coverage; 0 for a node
/// that is no fragment).
struct ApiOrder {
  size_t nthreads = 1;
  size_t count = 0;
};

std::string order_fragments(const NodeView& nodes, uint32_t draw_id, const std::vector<DrawPart>& parts, uint32_t width,
                            uint32_t height, BuildScratch& scratch, ApiOrder& api) {
  // The work is split over threads by nodes; each split's result is merged
  // in a fixed order, and the fragments are put into API order by unique
  // keys, so they depend neither on the thread count nor on the nodes' order.
  const size_t n = nodes.count;
  const size_t nthreads =
      n < (size_t(1) << 18) ? 1 : std::max<size_t>(1, std::min(8u, std::thread::hardware_concurrency()));
  api.nthreads = nthreads;
  auto kept = [&](size_t i) { return (nodes.state[i] & kNodeKept) != 0; };

  // Primitive numbering: each part's primitives per instance (the call's
  // count, or more when the kept nodes show more) and its instances.
  struct Extent {
    std::vector<uint64_t> per_instance, instances;
  };
  std::vector<Extent> ext(nthreads);
  in_parallel(nthreads, [&](size_t t) {
    Extent& e = ext[t];
    const auto [lo, hi] = slice(n, t, nthreads);
    for (size_t i = lo; i < hi; ++i) {
      if (!kept(i)) continue;
      const uint32_t* k = nodes.keys + 4 * i;
      if (k[2] >= e.per_instance.size()) {
        e.per_instance.resize(size_t(k[2]) + 1, 0);
        e.instances.resize(size_t(k[2]) + 1, 0);
      }
      e.per_instance[k[2]] = std::max<uint64_t>(e.per_instance[k[2]], uint64_t(k[0]) + 1);
      e.instances[k[2]] = std::max<uint64_t>(e.instances[k[2]], uint64_t(k[1]) + 1);
    }
  });
  std::vector<uint64_t> per_instance(parts.size(), 0), instances(parts.size(), 0);
  for (size_t k = 0; k < parts.size(); ++k) per_instance[k] = parts[k].prims_per_instance;
  for (const Extent& e : ext) {
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
  if (n > UINT32_MAX)
    return "draw " + std::to_string(draw_id) + " has " + std::to_string(n) +
           " fragment nodes, more than 32-bit indices number";

  // Counted a thread a range of nodes, then made into one array at each
  // range's place.
  // A node's coverage: the samples whose depth a pass wrote.
  const int spp = std::min(64, std::max(1, nodes.spp));
  auto coverage = [&](size_t i) {
    uint64_t c = 0;
    for (int s = 0; s < spp; ++s) c |= uint64_t(nodes.depth[size_t(s)][i] != kNoDepth) << s;
    return c;
  };
  // Each kept node's coverage (0 for the others), made while counting.
  scratch.coverage.ensure(n);
  LargeArray<uint64_t>& node_coverage = scratch.coverage;
  auto fragment_node = [&](size_t i) { return node_coverage[i] != 0; };
  std::vector<size_t> at(nthreads + 1, 0);
  in_parallel(nthreads, [&](size_t t) {
    const auto [lo, hi] = slice(n, t, nthreads);
    size_t c = 0;
    for (size_t i = lo; i < hi; ++i) {
      node_coverage[i] = (nodes.state[i] & kNodeKept) ? coverage(i) : 0;
      c += fragment_node(i) ? 1 : 0;
    }
    at[t + 1] = c;
  });
  for (size_t t = 0; t < nthreads; ++t) at[t + 1] += at[t];
  const size_t count = at[nthreads];
  scratch.order.ensure(count);
  std::vector<std::string> errors(nthreads);
  in_parallel(nthreads, [&](size_t t) {
    const auto [lo, hi] = slice(n, t, nthreads);
    OrderKey* m = scratch.order.data() + at[t];
    for (size_t i = lo; i < hi; ++i) {
      if (!fragment_node(i)) continue;
      const uint32_t pixel = nodes.state[i] & kNodePixel;
      const uint32_t x = pixel & 0xFFFF, gy = pixel >> 16;
      if (x >= width || gy >= height) {
        errors[t] = "draw " + std::to_string(draw_id) + ": a fragment at (" + std::to_string(x) + ", " +
                    std::to_string(gy) + ") is outside the " + std::to_string(width) + "x" + std::to_string(height) +
                    " target";
        return;
      }
      const uint32_t* k = nodes.keys + 4 * i;
      const uint64_t prim = base[k[2]] + uint64_t(k[1]) * per_instance[k[2]] + k[0];
      *m++ = OrderKey{prim << 32 | uint64_t(height - 1 - gy) << 16 | x, uint32_t(i)};
    }
  });
  for (const std::string& e : errors)
    if (!e.empty()) return e;
  // A stable least-significant-digit radix sort of the (unique) order keys:
  // a byte a pass, the bytes every key shares skipped.
  scratch.sorted.ensure(count);
  for (int shift = 0; shift < 64; shift += 8) {
    size_t at_byte[257] = {};
    const OrderKey* from = scratch.order.data();
    for (size_t j = 0; j < count; ++j) ++at_byte[((from[j].order >> shift) & 0xFF) + 1];
    if (std::any_of(at_byte + 1, at_byte + 257, [&](size_t c) { return c == count; })) continue;
    for (int b = 0; b < 256; ++b) at_byte[b + 1] += at_byte[b];
    OrderKey* to = scratch.sorted.data();
    for (size_t j = 0; j < count; ++j) to[at_byte[(from[j].order >> shift) & 0xFF]++] = from[j];
    std::swap(scratch.order, scratch.sorted);
  }
  api.count = count;
  return "";
}

}  // namespace

std::string build_fragments(const NodeView& nodes, uint32_t draw_id, const std::vector<DrawPart>& parts, bool clamp,
                            uint32_t width, uint32_t height, CapturedDraw& out) {
  ApiOrder api;
  BuildScratch scratch;
  if (std::string e = order_fragments(nodes, draw_id, parts, width, height, scratch, api); !e.empty()) return e;
  const size_t nthreads = api.nthreads;
  const OrderKey* order = scratch.order.data();
  const LargeArray<uint64_t>& node_coverage = scratch.coverage;
  std::vector<std::string> errors(nthreads);
  // The fragments in that order, a thread a range of them: first each
  // one's place among the depths.
  std::vector<size_t> z_at(api.count + 1, 0);
  for (size_t j = 0; j < api.count; ++j)
    z_at[j + 1] = z_at[j] + size_t(__builtin_popcountll(node_coverage[order[j].node]));
  const size_t first = 0, z_base = 0;
  out.fragments = LargeArray<CapturedFragment>(api.count);
  out.z = LargeArray<float>(z_at.back());
  in_parallel(nthreads, [&](size_t t) {
    const auto [lo, hi] = slice(api.count, t, nthreads);
    for (size_t j = lo; j < hi; ++j) {
      const size_t i = order[j].node;
      CapturedFragment& f = out.fragments[first + j];
      f.draw_id = draw_id;
      f.prim_id = uint32_t(order[j].order >> 32);
      f.y = uint16_t(order[j].order >> 16);
      f.x = uint16_t(order[j].order);
      f.coverage = node_coverage[i];
      f.z_first = z_base + z_at[j];
      float* z = out.z.data() + f.z_first;
      for (uint64_t m = f.coverage; m; m &= m - 1) {
        const float d = word_float(depth_bits(nodes.depth[size_t(__builtin_ctzll(m))][i]));
        if (!(d >= 0.0f && d <= 1.0f) && errors[t].empty())
          errors[t] =
              "draw " + std::to_string(draw_id) + ": a fragment's depth " + std::to_string(d) + " is not in [0, 1]";
        *z++ = d;
      }
      const float* c = nodes.colour + 4 * i;
      for (size_t k = 0; k < 4; ++k) f.rgba[k] = clamp || k == 3 ? clamp_unit(c[k]) : clamp_non_negative(c[k]);
    }
  });
  for (const std::string& e : errors)
    if (!e.empty()) return e;
  return "";
}

std::string build_records(const NodeView& nodes, uint32_t draw_id, const std::vector<DrawPart>& parts, bool clamp,
                          const TraceHeader& header, BuildScratch& scratch, const RecordSink& sink, EncodedDraw& out) {
  // Runs of kRun fragments, each encoded into the sort's other half (free
  // once the keys are sorted: one array of fresh memory fewer), which both
  // of the sort's arrays are made large enough for (the sort swaps them).
  constexpr size_t kRun = size_t(1) << 18;
  const size_t run_keys =
      (kRun * fragment_record_bytes(header, std::min(64, std::max(1, int(header.spp)))) + sizeof(OrderKey) - 1) /
      sizeof(OrderKey);
  scratch.order.ensure(run_keys);
  scratch.sorted.ensure(run_keys);
  ApiOrder api;
  if (std::string e = order_fragments(nodes, draw_id, parts, header.width, header.height, scratch, api); !e.empty())
    return e;
  uint8_t* const records = reinterpret_cast<uint8_t*>(scratch.sorted.data());
  const size_t nthreads = api.nthreads;
  const OrderKey* order = scratch.order.data();
  const uint64_t* node_coverage = scratch.coverage.data();
  out.count = api.count;
  out.covered_samples = 0;
  out.size = 0;
  // Each run encoded by the threads (a range of the run each, at the place
  // the records' sizes before it give) and then given to the sink.
  constexpr size_t kAhead = 8;  // fragments the encoding fetches ahead
  std::vector<size_t> at(nthreads + 1, 0), covered(nthreads, 0);
  std::vector<std::string> errors(nthreads);
  for (size_t run = 0; run < api.count; run += kRun) {
    const size_t run_end = std::min(api.count, run + kRun);
    in_parallel(nthreads, [&](size_t t) {
      auto [lo, hi] = slice(run_end - run, t, nthreads);
      size_t bytes = 0, samples = 0;
      for (size_t j = run + lo; j < run + hi; ++j) {
        const int c = __builtin_popcountll(node_coverage[order[j].node]);
        bytes += fragment_record_bytes(header, c);
        samples += size_t(c);
      }
      at[t + 1] = bytes;
      covered[t] = samples;
    });
    for (size_t t = 0; t < nthreads; ++t) {
      at[t + 1] += at[t];
      out.covered_samples += covered[t];
    }
    in_parallel(nthreads, [&](size_t t) {
      auto [lo, hi] = slice(run_end - run, t, nthreads);
      uint8_t* b = records + at[t];
      Fragment f;
      for (size_t j = run + lo; j < run + hi; ++j) {
        // The nodes are read in API order, not in memory order: a later
        // fragment's depths and colour fetched ahead (its coverage, read
        // when the sizes were counted, is in cache).
        if (j + kAhead < run + hi) {
          const size_t a = order[j + kAhead].node;
          for (uint64_t m = node_coverage[a]; m; m &= m - 1)
            __builtin_prefetch(nodes.depth[size_t(__builtin_ctzll(m))] + a);
          __builtin_prefetch(nodes.colour + 4 * a);
        }
        const size_t i = order[j].node;
        f.draw_id = draw_id;
        f.prim_id = uint32_t(order[j].order >> 32);
        f.y = uint16_t(order[j].order >> 16);
        f.x = uint16_t(order[j].order);
        f.coverage = node_coverage[i];
        for (uint64_t m = f.coverage; m; m &= m - 1) {
          const int s = __builtin_ctzll(m);
          f.z[size_t(s)] = word_float(depth_bits(nodes.depth[size_t(s)][i]));
        }
        const float* c = nodes.colour + 4 * i;
        for (size_t k = 0; k < 3; ++k) f.rgb[k] = clamp ? clamp_unit(c[k]) : clamp_non_negative(c[k]);
        f.alpha = clamp_unit(c[3]);
        std::string err;
        const size_t n = encode_fragment_record(header, f, b, err);
        if (n != fragment_record_bytes(header, __builtin_popcountll(f.coverage))) {
          errors[t] = "draw " + std::to_string(draw_id) + ": fragment (" + std::to_string(f.x) + ", " +
                      std::to_string(f.y) + ") of primitive " + std::to_string(f.prim_id) + ": " + err;
          return;
        }
        b += n;
      }
    });
    for (const std::string& e : errors)
      if (!e.empty()) return e;
    if (std::string e = sink(records, at[nthreads], run_end - run); !e.empty()) return e;
    out.size += at[nthreads];
  }
  return "";
}

std::string build_records(const NodeView& nodes, uint32_t draw_id, const std::vector<DrawPart>& parts, bool clamp,
                          const TraceHeader& header, EncodedDraw& out) {
  BuildScratch scratch;
  std::vector<uint8_t> all;
  const std::string e = build_records(
      nodes, draw_id, parts, clamp, header, scratch,
      [&](const uint8_t* r, size_t bytes, size_t) {
        all.insert(all.end(), r, r + bytes);
        return std::string();
      },
      out);
  out.bytes = LargeArray<uint8_t>(all.size());
  if (!all.empty()) std::memcpy(out.bytes.data(), all.data(), all.size());
  return e;
}

void* map_pages(size_t bytes) {
  void* p = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) throw std::bad_alloc();
  madvise(p, bytes, MADV_HUGEPAGE);  // advice: without huge pages the memory is the same, slower to fault in
  return p;
}

void unmap_pages(void* p, size_t bytes) { munmap(p, bytes); }

Fragment to_trace_fragment(const CapturedFragment& c, const float* z) {
  Fragment f;
  f.draw_id = c.draw_id;
  f.prim_id = c.prim_id;
  f.x = c.x;
  f.y = c.y;
  f.coverage = c.coverage;
  size_t k = 0;
  for (uint64_t m = c.coverage; m; m &= m - 1) f.z[size_t(__builtin_ctzll(m))] = z[c.z_first + k++];
  f.rgb = {c.rgba[0], c.rgba[1], c.rgba[2]};
  f.alpha = c.rgba[3];
  return f;
}

}  // namespace ropsim::glcapture
