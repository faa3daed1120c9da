#include "sim/fidelity/sampled/livepoints.h"

#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

#include "rtl_models/algo/bits.h"
#include "rtl_models/algo/compression.h"
#include "rtl_models/algo/depth.h"
#include "rtl_models/functional/functional_rop.h"
#include "rtl_models/golden/golden_model.h"
#include "rtl_models/memory/address_map.h"
#include "rtl_models/memory/line_set.h"
#include "rtl_models/top/memory_estimate.h"
#include "rtl_models/top/rop_pipeline.h"
#include "rtl_models/top/sim_context.h"
#include "rtl_models/units/distributor.h"
#include "sim/fidelity/sampled/livepoint_file.h"
#include "util/errors.h"
#include "util/host_threads.h"
#include "util/memory_budget.h"
#include "util/progress.h"
#include "util/worker_pool.h"

namespace ropsim {

namespace {

/// The pixels of tile (x0, y0) of st that hold written values, written to
/// out (room for 64); returns their number.
size_t tile_resident(const SampleStore& st, const PixelRef& clear, uint32_t x0, uint32_t y0, Resident* out) {
  size_t n = 0;
  const TraceHeader& h = st.header();
  uint32_t clear_z;
  std::memcpy(&clear_z, &clear.depth[0], sizeof clear_z);
  for (int p = 0; p < 64; ++p) {
    const uint32_t x = x0 + uint32_t(p & 7), y = y0 + uint32_t(p >> 3);
    if (x >= h.width || y >= h.height) continue;
    const PixelView v = st.view(x, y);
    if (!v.depth) return n;  // the golden model never touched the tile
    Resident r;
    r.x = uint16_t(x);
    r.y = uint16_t(y);
    for (int i = 0; i < h.spp; ++i) {
      uint32_t z;
      std::memcpy(&z, &v.depth[i], sizeof z);
      const uint16_t* c = &v.rgb[3 * i];
      if (z != clear_z || c[0] != clear.rgb[0] || c[1] != clear.rgb[1] || c[2] != clear.rgb[2])
        r.written |= uint64_t{1} << i;
    }
    r.tracker = v.tracker && !(*v.tracker == TrackerState{});
    r.layers = v.slab && v.slab->count > 0;
    if (r.written || r.tracker || r.layers) out[n++] = r;
  }
  return n;
}

/// A pixel's plane keys into out (spp of them): the store's, or the clear
/// key's where the store keeps none.
void copy_planes(const PixelView& v, size_t spp, uint64_t* out) {
  if (v.plane)
    std::memcpy(out, v.plane, spp * sizeof(uint64_t));
  else
    std::fill_n(out, spp, kClearPlaneKey);
}

/// Canonicalises lp's fragments and reads, from the model's lanes between
/// batches, the pre-state of the pixels they touch and the resident pixels of
/// those pixels' tiles (on the model's threads). resident and resident_n:
/// scratch kept across live-points.
void read_pre_state(const StochasticModel& model, const TraceHeader& h, const PixelRef& clear,
                    const PixelView& clear_view, LivePoint& lp, std::vector<Resident>& resident,
                    std::vector<size_t>& resident_n) {
  // The pixels and the 8x8 tiles they touch, each sorted by (y, x) and
  // (x0, y0); their pre-state read on the model's threads.
  std::vector<uint64_t> pixels, tiles;
  pixels.reserve(lp.fragments.size());
  tiles.reserve(lp.fragments.size());
  for (Fragment& x : lp.fragments) {
    canonicalise(h, x);
    pixels.push_back(uint64_t(x.y) << 16 | x.x);
    tiles.push_back(uint64_t(x.x & ~7u) << 16 | (x.y & ~7u));
  }
  for (auto* v : {&pixels, &tiles}) {
    std::sort(v->begin(), v->end());
    v->erase(std::unique(v->begin(), v->end()), v->end());
  }
  lp.pre.resize(pixels.size(), h.spp);
  // Each tile's resident pixels into its own 64 slots, then packed in
  // tile order. The lines of the pixel a few ahead are asked for while
  // one is copied (the pre-state is cold: last touched a period ago).
  resident.resize(tiles.size() * 64);
  resident_n.assign(tiles.size(), 0);
  constexpr size_t kAhead = 4;
  model.parallel_for(pixels.size() + tiles.size(), [&](size_t lo, size_t hi) {
    for (size_t j = lo; j < hi; ++j) {
      if (j < pixels.size()) {
        if (j + kAhead < std::min(hi, pixels.size())) {
          const uint32_t ax = uint32_t(pixels[j + kAhead] & 0xffff), ay = uint32_t(pixels[j + kAhead] >> 16);
          model.store_of(ax, ay).prefetch(ax, ay);
        }
        const uint32_t x = uint32_t(pixels[j] & 0xffff), y = uint32_t(pixels[j] >> 16);
        lp.pre.set(j, model.store_of(x, y), clear_view, x, y);
      } else {
        const size_t t = j - pixels.size();
        const uint32_t x0 = uint32_t(tiles[t] >> 16), y0 = uint32_t(tiles[t] & 0xffff);
        resident_n[t] = tile_resident(model.store_of(x0, y0), clear, x0, y0, &resident[t * 64]);
      }
    }
  });
  size_t n_resident = 0;
  for (size_t c : resident_n) n_resident += c;
  lp.resident.reserve(n_resident);
  for (size_t t = 0; t < tiles.size(); ++t)
    lp.resident.insert(lp.resident.end(), resident.begin() + std::ptrdiff_t(t * 64),
                       resident.begin() + std::ptrdiff_t(t * 64 + resident_n[t]));
  // The samples of the resident pixels with written values that no fragment
  // touches (TilePixels), in (y, x) order.
  std::vector<uint64_t> others;
  for (const Resident& r : lp.resident) {
    const uint64_t key = uint64_t(r.y) << 16 | r.x;
    if (r.written && !std::binary_search(pixels.begin(), pixels.end(), key)) others.push_back(key);
  }
  std::sort(others.begin(), others.end());
  const size_t spp = size_t(h.spp);
  TilePixels& tp = lp.tiles;
  tp.x.resize(others.size());
  tp.y.resize(others.size());
  tp.depth.resize(others.size() * spp);
  tp.rgb.resize(3 * others.size() * spp);
  tp.planes.resize(others.size() * spp);
  if (others.empty()) return;
  model.parallel_for(others.size(), [&](size_t lo, size_t hi) {
    for (size_t j = lo; j < hi; ++j) {
      const uint32_t x = uint32_t(others[j] & 0xffff), y = uint32_t(others[j] >> 16);
      const PixelView v = model.store_of(x, y).view(x, y);
      tp.x[j] = uint16_t(x);
      tp.y[j] = uint16_t(y);
      std::memcpy(&tp.depth[j * spp], v.depth, spp * sizeof(float));
      std::memcpy(&tp.rgb[3 * j * spp], v.rgb, 3 * spp * sizeof(uint16_t));
      copy_planes(v, spp, &tp.planes[j * spp]);
    }
  });
}

/// Calls f(line) for every line a touch reads or writes, in the order the
/// pipeline does (depth reads, tracker read, a blended draw's colour read,
/// then the writes).
template <class F>
void touch_lines(const Touch& x, const AddressMap& amap, bool tracker, bool slab, F&& f) {
  if (slab && !x.routed) {
    amap.for_each_layer_line(x.x, x.y, [&](uint64_t l) { f(l, false, Buffer::kLayers); });
    if (x.slab_kept) amap.for_each_layer_line(x.x, x.y, [&](uint64_t l) { f(l, true, Buffer::kLayers); });
    return;
  }
  const bool own = tracker && !x.routed;  // an opaque or blended draw bypasses the tracker
  amap.for_each_sample_line(Buffer::kDepth, x.x, x.y, x.covered, [&](uint64_t l) { f(l, false, Buffer::kDepth); });
  if (own) amap.for_each_tracker_line(x.x, x.y, [&](uint64_t l) { f(l, false, Buffer::kTracker); });
  if (x.routed && x.reads_colour)
    amap.for_each_sample_line(Buffer::kColor, x.x, x.y, x.written, [&](uint64_t l) { f(l, false, Buffer::kColor); });
  if (!x.reached_write) return;
  if (!x.routed || x.depth_write)
    amap.for_each_sample_line(Buffer::kDepth, x.x, x.y, x.written, [&](uint64_t l) { f(l, true, Buffer::kDepth); });
  amap.for_each_sample_line(Buffer::kColor, x.x, x.y, x.written, [&](uint64_t l) { f(l, true, Buffer::kColor); });
  if (own) amap.for_each_tracker_line(x.x, x.y, [&](uint64_t l) { f(l, true, Buffer::kTracker); });
}

/// The distinct lines the warming must reach: R x the design's cache lines.
uint64_t reach_lines(const HwConfig& hw, double reach) {
  const double lines = double(hw.distributor.rop_units) * double(hw.cache.size_bytes) / double(hw.cache.line_bytes);
  return uint64_t(std::ceil(std::max(0.0, reach) * lines));
}

/// Walks lp's touches backwards until they reach reach_lines distinct lines
/// (with compression, comp, also R times the design's metadata cache lines,
/// all ROPs, in distinct metadata lines: the state bits of a tile stay in a
/// metadata cache far longer than its data in a ROP cache); returns the index
/// of the first touch to warm with (0: all of them).
size_t warming_start(const LivePoint& lp, const AddressMap& amap, const HwConfig& hw, double reach, bool tracker,
                     bool slab, const CompressionModel* comp, bool& met) {
  const uint64_t want = reach_lines(hw, reach);
  const double meta_lines =
      double(hw.distributor.rop_units) *
      double(std::max(hw.compression.metadata_cache_bytes, hw.cache.line_bytes) / hw.cache.line_bytes);
  const uint64_t want_meta = comp && hw.compression.any() ? uint64_t(std::ceil(std::max(0.0, reach) * meta_lines)) : 0;
  LineSet seen(hw.cache.line_bytes), seen_meta(hw.cache.line_bytes);
  uint64_t distinct = 0, distinct_meta = 0;
  for (size_t i = lp.warming.size(); i-- > 0;) {
    if (distinct >= want && distinct_meta >= want_meta) {
      met = true;
      return i + 1;
    }
    touch_lines(lp.warming[i], amap, tracker, slab, [&](uint64_t l, bool, Buffer b) {
      if (!seen.contains(l)) {
        seen.insert(l);
        ++distinct;
      }
      if (want_meta && comp->compresses(b)) {
        const uint64_t m = comp->metadata_line(l, b);
        if (!seen_meta.contains(m)) {
          seen_meta.insert(m);
          ++distinct_meta;
        }
      }
    });
  }
  met = distinct >= want && distinct_meta >= want_meta;
  return 0;
}

}  // namespace

void PrePixels::resize(size_t n, int spp) {
  x.resize(n);
  y.resize(n);
  depth.resize(n * size_t(spp));
  rgb.resize(3 * n * size_t(spp));
  planes.resize(n * size_t(spp));
  if (tracker) trackers.resize(n);
  if (slab_bits > 0) slabs.resize(n);
}

void PrePixels::set(size_t i, const SampleStore& st, const PixelView& clear, uint32_t px, uint32_t py) {
  const size_t spp = size_t(st.header().spp);
  x[i] = uint16_t(px);
  y[i] = uint16_t(py);
  PixelView v = st.view(px, py);
  if (!v.depth) v = clear;  // never touched: the clear values
  std::memcpy(&depth[i * spp], v.depth, spp * sizeof(float));
  std::memcpy(&rgb[3 * i * spp], v.rgb, 3 * spp * sizeof(uint16_t));
  copy_planes(v, spp, &planes[i * spp]);
  if (tracker) trackers[i] = *v.tracker;
  if (slab_bits > 0) slabs[i] = *v.slab;
}

void PrePixels::apply(SampleStore& st) const {
  const size_t spp = size_t(st.header().spp);
  invariant(st.has_tracker() == tracker && st.targets().slab_bits == slab_bits,
            "a live-point's pre-state goes into a store of the same buffers");
  for (size_t i = 0; i < size(); ++i) {
    const PixelRef r = st.pixel(x[i], y[i]);
    std::memcpy(r.depth, &depth[i * spp], spp * sizeof(float));
    std::memcpy(r.rgb, &rgb[3 * i * spp], 3 * spp * sizeof(uint16_t));
    if (r.plane) std::memcpy(r.plane, &planes[i * spp], spp * sizeof(uint64_t));
    if (tracker) *r.tracker = trackers[i];
    if (slab_bits > 0) *r.slab = slabs[i];
  }
}

void TilePixels::apply(SampleStore& st) const {
  const size_t spp = size_t(st.header().spp);
  for (size_t i = 0; i < size(); ++i) {
    const PixelRef r = st.pixel(x[i], y[i]);
    std::memcpy(r.depth, &depth[i * spp], spp * sizeof(float));
    std::memcpy(r.rgb, &rgb[3 * i * spp], 3 * spp * sizeof(uint16_t));
    if (r.plane) std::memcpy(r.plane, &planes[i * spp], spp * sizeof(uint64_t));
  }
}

size_t TilePixels::bytes() const {
  return x.capacity() * 2 + y.capacity() * 2 + depth.capacity() * sizeof(float) + rgb.capacity() * 2 +
         planes.capacity() * sizeof(uint64_t);
}

size_t PrePixels::bytes() const {
  return x.capacity() * 2 + y.capacity() * 2 + depth.capacity() * sizeof(float) + rgb.capacity() * 2 +
         planes.capacity() * sizeof(uint64_t) + trackers.capacity() * sizeof(TrackerState) +
         slabs.capacity() * sizeof(SlabPixel);
}

void LivePoints::charge(const LivePoint& p) {
  mem.add(p.fragments.capacity() * sizeof(Fragment) + p.warming.capacity() * sizeof(Touch) +
              p.resident.capacity() * sizeof(Resident) + p.pre.bytes() + p.tiles.bytes(),
          "the live-points' fragments, pre-states and touches");
}

LivePoints record_livepoints(const InputSpec& in, const MethodConfig& method, const SamplingParams& p, int threads) {
  if (method.method == Method::kReference) throw UserError("sampled: the reference method has no ROP pipeline");
  if (passes_of(method.method).count != 1 || has_blend_pass(method.method))
    throw UserError(std::string("sampled simulation runs single-pass methods without blend targets; ") +
                    to_string(method.method) + " is not one");
  if (p.unit_fragments == 0 || p.units == 0) throw UserError("sampled: the unit size and the unit count must be >= 1");
  LivePoints lib;
  lib.method = method;
  lib.params = p;
  auto src = open_fragments(in);
  // slab runs a frame with opaque or blended draws in two passes (a pre-pass first).
  if (run_passes(src->header(), method.method).count != 1)
    throw UserError(std::string("sampled simulation runs single-pass methods; ") + to_string(method.method) + " on " +
                    in.describe() +
                    " draws its opaque and blended draws in a pre-pass first (run it at the functional, approximate "
                    "or cycle fidelity)");
  if (const std::optional<uint64_t> known = src->fragments_known()) {
    lib.fragments = *known;  // N from the trace's header (the reader holds the trace to it)
  } else {                   // N: the sampling design needs the input's length
    auto counting = open_fragments(in);
    Progress progress("live-points: counting the input", "fragments");
    for (Fragment f; counting->next(f);)
      if (++lib.fragments % 65536 == 0) progress.update(counting->consumed(), lib.fragments);
    progress.update(1.0, lib.fragments);
    progress.finish();
  }
  lib.header = src->header();
  lib.input = input_identity(in);
  const uint64_t n = lib.fragments;
  lib.params = placed_sampling(p, n, &lib.whole);
  const uint64_t k_units = lib.params.units;
  // The plan below grows with N and K, which a trace's header gives: charged
  // first, so a header that claims too much is refused by --memory-limit
  // naming the input, not met by the allocator.
  constexpr size_t kBatch = 4096;
  struct Segment {
    uint64_t first, count;
    size_t point;   // k of the live-point, or kPlain
    bool observed;  // within a live-point's warming (or one)
  };
  const size_t ring_size = size_t(std::min<uint64_t>(p.warming_fragments, n));
  // Segments: the K points, and the batches of the K + 1 gaps between them,
  // each gap cut at most twice more than its length in batches.
  const uint64_t max_segments = n / kBatch + 3 * (k_units + 1);
  BudgetShare plan_mem;
  plan_mem.add(3 * k_units * sizeof(uint64_t) + max_segments * sizeof(Segment) + ring_size * sizeof(Touch),
               "the live-points' placement and warming ring, for " + in.describe());
  std::vector<uint64_t> starts(k_units), firsts(k_units), ends(k_units);
  uint64_t prev_end = 0;
  for (uint64_t k = 0; k < k_units; ++k) {
    const UnitSpan span = unit_span(n, lib.params, k, prev_end);
    starts[k] = span.start;
    firsts[k] = span.first;
    ends[k] = span.end;
    prev_end = ends[k];
  }

  // The golden model on `threads` threads (golden_model.h: the same state
  // for every thread count), drawn in batches that end where a live-point
  // begins, so its pre-state is read between batches, from the lanes.
  // Its stores keep each depth's plane key, which a design with the
  // rasterizer-plane depth encoder reads from the pre-state (compression.h).
  CompressionSetup keys;
  keys.depth = true;
  keys.format.depth_encoder = DepthEncoder::kPlane;
  StochasticModel model(lib.header, on_design(method, keys), threads > 0 ? threads : host_threads());
  const SampleStore& st0 = model.store_of(0, 0);
  // The clear values, from a tile allocated cleared.
  SampleStore cleared(lib.header, st0.has_tracker(), st0.targets());
  const PixelRef clear = cleared.pixel(0, 0);
  const PixelView clear_view = cleared.view(0, 0);
  // The last T fragments' touches, a ring, written in place by the observer:
  // of a batch of m, fragment i >= m - T goes to slot ring_at + i - skip
  // (distinct slots, so the lanes' threads never write one twice).
  std::vector<Touch> ring(ring_size);
  size_t ring_at = 0, ring_fill = 0, skip = 0;
  const bool slab = method.method == Method::kSlab;
  const auto observe = [&ring, &ring_at, &skip, ring_size, slab](size_t i, const FragWork& w) {
    if (i < skip) return;
    size_t at = ring_at + i - skip;
    if (at >= ring_size) at -= ring_size;
    Touch& t = ring[at];
    t = touch_of(w, slab);
  };
  bool observing = false;
  // Only the T fragments before each live-point (and the live-points' own,
  // which the next one's T may reach back into) are observed: a batch that
  // no live-point's warming reaches is drawn without the observer, and
  // empties the ring (nothing before it is within T of a later live-point).
  auto draw = [&](const Fragment* f, size_t m, const std::function<void()>& beside, bool observed) {
    observed = observed && ring_size > 0;
    if (observed != observing) {
      model.set_observer(observed ? std::function<void(size_t, const FragWork&)>(observe) : nullptr);
      observing = observed;
    }
    if (!observed) {
      model.draw_batch(f, m, beside);
      ring_at = ring_fill = 0;
      return;
    }
    skip = m > ring_size ? m - ring_size : 0;
    model.draw_batch(f, m, beside);
    ring_at = (ring_at + (m - skip)) % ring_size;
    ring_fill = std::min(ring_fill + (m - skip), ring_size);
  };
  // The input as segments in order: batches of at most kBatch fragments
  // between live-points, each ending where the next live-point begins or its
  // warming (T fragments before it) does, and the live-points' fragments.
  // While the model draws one segment (on its threads), this thread reads the
  // next.
  constexpr size_t kPlain = ~size_t{0};
  std::vector<Segment> segments;
  segments.reserve(size_t(max_segments));
  for (uint64_t at = 0, kk = 0; at < n || kk < k_units;) {
    const uint64_t stop = kk < k_units ? firsts[kk] : n;
    const uint64_t warm = kk < k_units ? stop - std::min<uint64_t>(stop, ring_size) : n;
    if (at < stop) {
      const uint64_t m = std::min<uint64_t>(kBatch, (at < warm ? warm : stop) - at);
      segments.push_back(Segment{at, m, kPlain, at >= warm});
      at += m;
      continue;
    }
    if (kk == k_units) break;
    segments.push_back(Segment{firsts[kk], ends[kk] - firsts[kk], size_t(kk), true});
    at = ends[kk];
    ++kk;
  }
  uint64_t i = 0;
  size_t k = 0;
  Fragment f;
  // Read in place: a buffer keeps its fragments' storage from batch to batch.
  auto read_segment = [&](const Segment& sg, std::vector<Fragment>& out) {
    out.resize(size_t(sg.count));
    size_t got = 0;
    while (got < out.size() && src->next(out[got])) ++got;
    invariant(got == sg.count, "the input delivers the fragments it was counted with");
  };
  std::vector<Resident> resident;  // a live-point's, 64 slots per tile
  std::vector<size_t> resident_n;
  std::vector<Fragment> cur, next;
  if (!segments.empty()) read_segment(segments[0], cur);
  Progress progress("live-points: recording", "fragments");
  for (size_t si = 0; si < segments.size(); ++si) {
    progress.update(n ? double(i) / double(n) : 1.0, i);
    const Segment& sg = segments[si];
    invariant(sg.first == i, "the segments cover the input in order");
    const std::function<void()> read_next = [&] {
      if (si + 1 < segments.size()) read_segment(segments[si + 1], next);
    };
    if (sg.point == kPlain) {
      draw(cur.data(), cur.size(), read_next, sg.observed);
    } else {
      const size_t kk = sg.point;
      LivePoint lp;
      lp.first = firsts[kk];
      lp.warmup = starts[kk] - firsts[kk];
      lp.window = lib.params.unit_fragments;
      lp.fragments = std::move(cur);
      lp.pre.tracker = st0.has_tracker();
      lp.pre.slab_bits = st0.targets().slab_bits;
      read_pre_state(model, lib.header, clear, clear_view, lp, resident, resident_n);
      // The ring's last ring_fill touches, oldest first: at most two runs.
      const size_t oldest = (ring_at + ring_size - ring_fill) % std::max<size_t>(ring_size, 1);
      const size_t first_run = std::min(ring_fill, ring_size - oldest);
      lp.warming.reserve(ring_fill);
      lp.warming.insert(lp.warming.end(), ring.begin() + std::ptrdiff_t(oldest),
                        ring.begin() + std::ptrdiff_t(oldest + first_run));
      lp.warming.insert(lp.warming.end(), ring.begin(), ring.begin() + std::ptrdiff_t(ring_fill - first_run));
      for (size_t j = 0; j < lp.fragments.size(); j += kBatch)
        draw(&lp.fragments[j], std::min<size_t>(kBatch, lp.fragments.size() - j),
             j == 0 ? read_next : std::function<void()>{}, true);
      k = kk + 1;
      lib.charge(lp);
      lib.points.push_back(std::move(lp));
      cur.clear();
    }
    i += sg.count;
    cur.swap(next);
  }
  invariant(k == k_units && i == n && !src->next(f), "every live-point is recorded in one pass over the input");
  invariant(segments.size() <= max_segments, "the plan holds no more segments than it was charged for");
  progress.update(1.0, n);
  progress.finish();
  model.set_observer({});
  lib.counters = model.counters();
  lib.image = model.resolve();
  return lib;
}

namespace {

/// Calls f(a, b) for every count of two CompressionTraffic (same field).
template <class A, class B, class F>
void each_count(A& a, B& b, F&& f) {
  for (size_t i = 0; i < size_t(kBuffers); ++i) {
    f(a.lines_written[i], b.lines_written[i]);
    f(a.lines_read[i], b.lines_read[i]);
    f(a.bytes_written_uncompressed[i], b.bytes_written_uncompressed[i]);
    f(a.bytes_written[i], b.bytes_written[i]);
    f(a.bytes_read_uncompressed[i], b.bytes_read_uncompressed[i]);
    f(a.bytes_read[i], b.bytes_read[i]);
    for (size_t j = 0; j < 4; ++j) f(a.writes_per_class[i][j], b.writes_per_class[i][j]);
    f(a.writes_cleared[i], b.writes_cleared[i]);
    f(a.metadata_bytes_read[i], b.metadata_bytes_read[i]);
    f(a.metadata_bytes_written[i], b.metadata_bytes_written[i]);
  }
  f(a.metadata_hits, b.metadata_hits);
  f(a.metadata_misses, b.metadata_misses);
  f(a.hiz_tests, b.hiz_tests);
  f(a.hiz_rejected, b.hiz_rejected);
  f(a.hiz_lines_skipped, b.hiz_lines_skipped);
}

CompressionTraffic difference(const CompressionTraffic& a, const CompressionTraffic& b) {
  CompressionTraffic d = a;
  each_count(d, b, [](uint64_t& x, const uint64_t& y) { x -= y; });
  return d;
}

/// The compression state a full run would hold at lp's first fragment,
/// warmed as the caches are (livepoints.h): every memory tile of the unit's
/// 8 x 8 tiles taken as written back with its contents then (its state bits
/// and Hi-Z bound; one holding only the clear value never written); a tile
/// outside them, which only the warming's lines reach, takes a class in the
/// proportions of the unit's tiles' classes. Each written-back tile's state
/// bits are written through the metadata cache of the ROP that owns it, as
/// the least recent accesses; the caches' tag-only warming then warms the
/// metadata caches with its fills and write-backs.
void warm_compression(CompressionModel& comp, StoreTileSource& src, const LivePoint& lp, const TraceHeader& h,
                      const HwConfig& hw, const AddressMap& amap) {
  const RopOwnership owner(hw.distributor, h.width);
  const uint32_t tp = hw.compression.tile_pixels;
  const uint64_t tiles_x = ceil_div(h.width, 8u), per = 64u / hw.compression.tile_pixels;
  std::vector<uint64_t> tiles;
  tiles.reserve(lp.pre.size() + lp.tiles.size());
  for (size_t i = 0; i < lp.pre.size(); ++i) tiles.push_back((lp.pre.y[i] >> 3) * tiles_x + (lp.pre.x[i] >> 3));
  for (size_t i = 0; i < lp.tiles.size(); ++i) tiles.push_back((lp.tiles.y[i] >> 3) * tiles_x + (lp.tiles.x[i] >> 3));
  std::sort(tiles.begin(), tiles.end());
  tiles.erase(std::unique(tiles.begin(), tiles.end()), tiles.end());
  for (size_t b = 0; b < size_t(kBuffers); ++b) {
    if (!comp.tile_count(Buffer(b))) continue;
    std::array<uint64_t, 4> classes{};
    for (uint64_t t : tiles)
      for (uint64_t m = t * per; m < (t + 1) * per; ++m) {
        const TileInfo ti = comp.warm_tile(Buffer(b), m);
        if (ti.cleared) continue;
        ++classes[size_t(ti.size_class)];
        // Its write-back wrote its state bits through the metadata cache of
        // the ROP that owns it, before the warming's touches.
        if (!comp.compresses(Buffer(b)) || (Buffer(b) != Buffer::kDepth && Buffer(b) != Buffer::kColor)) continue;
        const uint32_t first = uint32_t(m - t * per) * tp;  // the memory tile's first pixel in its 8 x 8 tile
        const uint32_t x = uint32_t(t % tiles_x) * 8 + first % 8, y = uint32_t(t / tiles_x) * 8 + first / 8;
        comp.warm_metadata(amap.pixel_address(Buffer(b), x, y), Buffer(b), true, owner.rop_of(x, y));
      }
    src.set_absent(Buffer(b), classes, canonical_depth(h.clear_depth));
  }
}

}  // namespace

UnitRun simulate_livepoint(const LivePoints& lib, size_t unit, const HwConfig& hw) {
  invariant(unit < lib.points.size(), "simulate_livepoint is given one of the library's units");
  const LivePoint& lp = lib.points[unit];
  const TraceHeader& h = lib.header;
  auto rop = std::make_unique<FunctionalRop>(h, on_design(lib.method, hw.compression.setup()));
  LineSet in_dram(hw.cache.line_bytes);
  const AddressMap amap(h.width, h.spp, rop->setup().tracker_bytes, hw.cache.line_bytes, rop->setup().bytes.stored,
                        rop->setup().slab_bytes);
  const bool tracker = rop->store().has_tracker(), slab = rop->store().has_slab();
  auto insert = [&in_dram](uint64_t line) { in_dram.insert(line); };
  lp.pre.apply(rop->store());
  // Compression and Hi-Z see whole memory tiles: the unit's tiles' other
  // written pixels too.
  const bool compression = hw.compression.any() || hw.hiz.enable;
  if (compression) lp.tiles.apply(rop->store());
  // A line that holds a written value is taken to be in DRAM (see livepoints.h).
  for (const Resident& p : lp.resident) {
    if (p.written) {
      amap.for_each_sample_line(Buffer::kDepth, p.x, p.y, p.written, insert);
      amap.for_each_sample_line(Buffer::kColor, p.x, p.y, p.written, insert);
    }
    if (p.tracker) amap.for_each_tracker_line(p.x, p.y, insert);
    if (p.layers) amap.for_each_layer_line(p.x, p.y, insert);
  }

  UnitRun r;
  const uint64_t warm = lp.warmup, end = lp.warmup + lp.window, all = lp.fragments.size();
  uint64_t retired = 0, c0 = 0, c1 = 0, w0 = 0, w1 = 0;
  DramStats d0, d1;
  {
    FreshSimContext sim;
    auto top = std::make_unique<RopPipeline>("unit", fragments_from(h, lp.fragments), *rop, in_dram, hw);
    top->set_decoupled(true);
    RopPipeline* t = top.get();
    // Compression and Hi-Z (compression_model.h), warmed as the caches are.
    std::unique_ptr<CompressionModel> comp;
    std::unique_ptr<StoreTileSource> tiles;
    if (compression) {
      comp = std::make_unique<CompressionModel>(hw, h.width, h.height, h.spp, compressed_bytes_per_sample(*rop),
                                                canonical_depth(h.clear_depth), hw.distributor.rop_units);
      tiles = std::make_unique<StoreTileSource>(rop->store(), hw.compression.setup().format);
      comp->set_source(tiles.get());
      warm_compression(*comp, *tiles, lp, h, hw, amap);
      top->compress_with(comp.get());
    }
    // Tag-only warming: the touches before the warm-up that reach R times the
    // design's cache lines (at most T), in order, through the caches of the
    // ROPs that own their pixels (depth test reads, then the writeback's writes).
    const RopOwnership owner(hw.distributor, h.width);
    bool met = false;
    const size_t from = warming_start(lp, amap, hw, lib.params.warming_reach, tracker, slab, comp.get(), met);
    r.warming_used = lp.warming.size() - from;
    r.warming_short = !met && lp.first > lp.warming.size();
    if (comp) {
      // A line the warming reads outside the unit's tiles is taken to be in
      // DRAM (its fill reads its tile's state bits): the live-point holds
      // which lines held written values for the unit's tiles only.
      for (size_t i = from; i < lp.warming.size(); ++i)
        touch_lines(lp.warming[i], amap, tracker, slab, [&](uint64_t l, bool write, Buffer) {
          const Touch& x = lp.warming[i];
          if (!write && !rop->store().tile_map().find(x.x, x.y)) in_dram.insert(l);
        });
    }
    for (size_t i = from; i < lp.warming.size(); ++i) {
      const Touch& x = lp.warming[i];
      RopCache& c = *t->caches()[owner.rop_of(x.x, x.y)];
      touch_lines(x, amap, tracker, slab, [&c](uint64_t l, bool write, Buffer b) { c.warm(l, write, b); });
    }
    auto dirtied = [t] {
      uint64_t n = 0;
      for (const auto& c : t->caches()) n += c->stats().dirtied;
      return n;
    };
    auto dirtied_of = [t] {
      std::array<uint64_t, kBuffers> n{};
      for (const auto& c : t->caches())
        for (size_t b = 0; b < size_t(kBuffers); ++b) n[b] += c->stats().dirtied_of[b];
      return n;
    };
    if (comp) r.warmed = comp->warm_state();
    w0 = dirtied();  // (warming counts nothing; a unit without warm-up measures from here)
    std::array<uint64_t, kBuffers> wb0 = dirtied_of(), wb1{};
    CompressionTraffic cs0, cs1;
    t->retirement().hook = [&, t](const FragToken&, uint64_t cycle) {
      ++retired;
      if (retired == warm) {
        c0 = cycle;
        d0 = t->dram().stats();
        w0 = dirtied();
        wb0 = dirtied_of();
        if (comp) cs0 = comp->stats();
      }
      if (retired == end) {
        c1 = cycle;
        d1 = t->dram().stats();
        w1 = dirtied();
        wb1 = dirtied_of();
        if (comp) cs1 = comp->stats();
      }
    };
    top->run();
    if (comp) {
      r.compression = true;
      r.run_compression = comp->stats();
      r.window_compression = difference(cs1, cs0);
      r.tail_compression = difference(r.run_compression, cs1);
      for (size_t b = 0; b < size_t(kBuffers); ++b) r.window_lines_dirtied_of[b] = wb1[b] - wb0[b];
    }
    const DramStats fin = top->dram().stats();
    invariant(retired == all, "a unit's run retires every fragment of its live-point");
    r.total_cycles = top->total_cycles();
    r.window_cycles = c1 - c0;
    r.window_bytes_read = d1.total_bytes_read() - d0.total_bytes_read();
    r.window_bytes_written = d1.total_bytes_written() - d0.total_bytes_written();
    r.tail_cycles = r.total_cycles - c1;
    r.tail_bytes_read = fin.total_bytes_read() - d1.total_bytes_read();
    r.tail_bytes_written = fin.total_bytes_written() - d1.total_bytes_written();
    r.window_lines_dirtied = w1 - w0;
    r.tail_lines_dirtied = dirtied() - w1;
    r.dram_max_channel_busy = fin.max_channel_busy;
    r.dram_max_channel_service = fin.max_channel_service;
    for (const auto& u : top->units())
      r.units.push_back(UnitReport{u.unit->name(), u.kind, u.rop, u.unit->stats(), {}});
  }
  r.state = std::make_unique<SampleStore>(std::move(rop->store()));
  return r;
}

UnitSpan unit_span(uint64_t n, const SamplingParams& p, uint64_t k, uint64_t prev_end) {
  const uint64_t units = p.units, u = p.unit_fragments, period = units ? n / units : 0;
  UnitSpan s;
  s.start = n - u - (units - 1 - k) * period;
  s.first = s.start - std::min<uint64_t>(p.warmup_fragments, s.start - prev_end);
  s.end = s.start + u + (k + 1 < units ? p.cooldown_fragments : 0);
  return s;
}

SamplingParams placed_sampling(const SamplingParams& p, uint64_t n, bool* whole_out) {
  SamplingParams placed = p;
  uint64_t u = std::min<uint64_t>(p.unit_fragments, std::max<uint64_t>(n, 1));
  uint64_t k_units = std::max<uint64_t>(1, std::min<uint64_t>(p.units, n / u));
  // An input so small that the units would simulate a large share of it in
  // detail anyway is simulated whole, as one unit without warm-up: exactly
  // the full cycle run, faster than sampling it.
  const double detailed = double(k_units) * double(p.warmup_fragments + u + p.cooldown_fragments);
  const bool whole = n == 0 || detailed >= p.max_detailed_share * double(n);
  if (whole) {
    u = n;
    k_units = 1;
  }
  const uint64_t period = k_units ? n / k_units : 0;  // >= u
  placed.unit_fragments = u;
  placed.units = k_units;
  // Each unit but the last has C fragments of cool-down after it, within the
  // period (the recording reads a live-point's fragments once).
  placed.cooldown_fragments = std::min<uint64_t>(p.cooldown_fragments, period - u);
  if (whole) placed.warmup_fragments = 0;
  if (whole_out) *whole_out = whole;
  return placed;
}

double student_t975(uint64_t dof) {
  static const double kTable[31] = {0,     12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228,
                                    2.201, 2.179,  2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080,
                                    2.074, 2.069,  2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042};
  if (dof == 0) return std::numeric_limits<double>::infinity();
  if (dof <= 30) return kTable[dof];
  // Linear in 1 / dof between the tabulated 30, 40, 60, 120 and infinity.
  static const double kDof[5] = {30, 40, 60, 120, 1e300}, kT[5] = {2.042, 2.021, 2.000, 1.980, 1.960};
  const double x = 1.0 / double(dof);
  for (int j = 0; j < 4; ++j)
    if (double(dof) <= kDof[j + 1]) {
      const double a = 1.0 / kDof[j], b = j + 1 == 4 ? 0.0 : 1.0 / kDof[j + 1];
      return kT[j + 1] + (kT[j] - kT[j + 1]) * (x - b) / (a - b);
    }
  return 1.960;
}

namespace {

/// What the estimate takes of one unit's run: what a worker sends back.
struct UnitFigures {
  uint64_t window_cycles = 0, window_bytes_read = 0, window_lines_dirtied = 0;
  uint64_t tail_cycles = 0, tail_bytes_read = 0, tail_lines_dirtied = 0, total_cycles = 0, dram_max_channel_busy = 0;
  uint64_t dram_max_channel_service = 0;
  uint64_t fragments = 0;  ///< of its live-point
  uint64_t warming_used = 0, warming_short = 0;
  std::vector<UnitReport> units;
  uint64_t window_bytes_written = 0, tail_bytes_written = 0;
  uint64_t compression = 0;  ///< 1: the design has compression or Hi-Z
  CompressionTraffic window_compression, tail_compression, run_compression;
  std::array<uint64_t, kBuffers> window_lines_dirtied_of{};
};

UnitFigures figures_of(const UnitRun& r, uint64_t fragments) {
  UnitFigures f;
  f.window_cycles = r.window_cycles;
  f.window_bytes_read = r.window_bytes_read;
  f.window_lines_dirtied = r.window_lines_dirtied;
  f.tail_cycles = r.tail_cycles;
  f.tail_bytes_read = r.tail_bytes_read;
  f.tail_lines_dirtied = r.tail_lines_dirtied;
  f.total_cycles = r.total_cycles;
  f.dram_max_channel_busy = r.dram_max_channel_busy;
  f.dram_max_channel_service = r.dram_max_channel_service;
  f.fragments = fragments;
  f.warming_used = r.warming_used;
  f.warming_short = r.warming_short;
  f.units = r.units;
  f.window_bytes_written = r.window_bytes_written;
  f.tail_bytes_written = r.tail_bytes_written;
  f.compression = r.compression;
  f.window_compression = r.window_compression;
  f.tail_compression = r.tail_compression;
  f.run_compression = r.run_compression;
  f.window_lines_dirtied_of = r.window_lines_dirtied_of;
  return f;
}

// The message a worker writes per unit: little-endian words and
// length-prefixed strings.
void put64(std::string& m, uint64_t v) {
  for (int i = 0; i < 8; ++i) m.push_back(char(uint8_t(v >> (8 * i))));
}
void put_str(std::string& m, const std::string& s) {
  put64(m, s.size());
  m += s;
}

std::string encode_figures(uint64_t unit, const UnitFigures& f) {
  std::string m;
  for (uint64_t v : {unit, f.window_cycles, f.window_bytes_read, f.window_lines_dirtied, f.tail_cycles,
                     f.tail_bytes_read, f.total_cycles, f.dram_max_channel_busy, f.dram_max_channel_service,
                     f.fragments, f.warming_used, f.warming_short})
    put64(m, v);
  put64(m, f.units.size());
  for (const UnitReport& u : f.units) {
    put_str(m, u.name);
    put_str(m, u.kind);
    put64(m, uint64_t(int64_t(u.rop)));
    for (uint64_t c : u.stats.cycles) put64(m, c);
    put64(m, u.stats.fragments);
    put64(m, u.stats.samples);
    put64(m, u.stats.activations);
  }
  for (uint64_t v : {f.window_bytes_written, f.tail_bytes_written, f.compression}) put64(m, v);
  for (const CompressionTraffic* c : {&f.window_compression, &f.tail_compression, &f.run_compression})
    each_count(*c, *c, [&m](const uint64_t& v, const uint64_t&) { put64(m, v); });
  for (uint64_t v : f.window_lines_dirtied_of) put64(m, v);
  return m;
}

struct MessageReader {
  const std::string& m;
  size_t at = 0;
  uint64_t u64() {
    invariant(at + 8 <= m.size(), "a worker's message holds every figure of its unit");
    uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= uint64_t(uint8_t(m[at + size_t(i)])) << (8 * i);
    at += 8;
    return v;
  }
  std::string str() {
    const uint64_t n = u64();
    invariant(at + n <= m.size(), "a worker's message holds every figure of its unit");
    std::string s = m.substr(at, size_t(n));
    at += size_t(n);
    return s;
  }
};

UnitFigures decode_figures(const std::string& m, uint64_t& unit) {
  MessageReader r{m};
  UnitFigures f;
  unit = r.u64();
  for (uint64_t* v : {&f.window_cycles, &f.window_bytes_read, &f.window_lines_dirtied, &f.tail_cycles,
                      &f.tail_bytes_read, &f.total_cycles, &f.dram_max_channel_busy, &f.dram_max_channel_service,
                      &f.fragments, &f.warming_used, &f.warming_short})
    *v = r.u64();
  f.units.resize(size_t(r.u64()));
  for (UnitReport& u : f.units) {
    u.name = r.str();
    u.kind = r.str();
    u.rop = int(int64_t(r.u64()));
    for (uint64_t& c : u.stats.cycles) c = r.u64();
    u.stats.fragments = r.u64();
    u.stats.samples = r.u64();
    u.stats.activations = r.u64();
  }
  for (uint64_t* v : {&f.window_bytes_written, &f.tail_bytes_written, &f.compression}) *v = r.u64();
  for (CompressionTraffic* c : {&f.window_compression, &f.tail_compression, &f.run_compression})
    each_count(*c, *c, [&r](uint64_t& v, uint64_t&) { v = r.u64(); });
  for (uint64_t& v : f.window_lines_dirtied_of) v = r.u64();
  invariant(r.at == m.size(), "a worker's message ends with its unit's figures");
  return f;
}

double process_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

/// Runs every unit in `jobs` worker processes (worker_pool.h), each unit a
/// task as the workers free up; the figures by unit index, which do not
/// depend on the workers (each unit is simulated from its live-point alone).
std::vector<UnitFigures> run_workers(const LivePoints& lib, const HwConfig& hw, int jobs, double& cpu_seconds) {
  const size_t k = lib.points.size();
  Progress progress("sampled: units", "units");
  WorkerPool pool(size_t(jobs), [&lib, &hw](const std::string& task) {
    test_hook_internal_error("livepoint-worker");  // tests/test_errors.cpp
    const size_t i = size_t(std::stoull(task));
    return encode_figures(i, figures_of(simulate_livepoint(lib, i, hw), lib.points[i].fragments.size()));
  });
  std::vector<UnitFigures> out(k);
  std::vector<bool> got(k, false);
  size_t next = 0, done = 0;
  std::string failure;
  int failure_status = 0;
  auto dispatch = [&] {
    for (size_t w = 0; w < pool.size() && next < k && failure.empty(); ++w)
      if (pool.idle(w)) pool.send(w, std::to_string(next++));
  };
  for (dispatch(); pool.any_busy(); dispatch()) {
    const WorkerPool::Reply r = pool.next();
    if (!r.ok()) {
      if (failure.empty()) {
        // The first failure ends the run (the rest finish their units).
        const bool died = r.kind == WorkerPool::Reply::Kind::kDied;
        failure = died ? "a worker process ended without its results (" + r.text + ")" : r.text;
        failure_status = died ? kInternalErrorStatus : r.status;
      }
      continue;
    }
    uint64_t unit = 0;
    UnitFigures f = decode_figures(r.text, unit);
    invariant(unit < k && !got[unit], "each unit is simulated by one worker, once");
    got[unit] = true;
    out[unit] = std::move(f);
    ++done;
    progress.update(double(done) / double(std::max<size_t>(k, 1)), done);
  }
  progress.finish();
  cpu_seconds = pool.close();
  if (!failure.empty()) {
    if (failure_status == kUserErrorStatus) throw UserError(failure);
    throw InternalError(failure);
  }
  for (bool g : got) invariant(g, "every unit's figures come back from a worker");
  return out;
}

}  // namespace

/// A design with compression or Hi-Z: DRAM bytes written and the compression
/// traffic (out.stats.compression) estimated from the units. A line made
/// dirty is written once, in its tile's block size at that write-back: the
/// window's lines dirtied per surface times the bytes per line the units'
/// write-backs of that surface moved (compressed / uncompressed, over every
/// unit), plus its metadata lines written. A whole input: the run's figures.
template <class Est>
void estimate_compression(const LivePoints& lib, const HwConfig& hw, const std::vector<UnitFigures>& figs,
                          const std::vector<double>& m, const Est& estimate, SampledRun& out) {
  const size_t k = figs.size();
  const double lb = double(hw.cache.line_bytes);
  CompressionTraffic run, win, tail = figs.back().tail_compression;
  std::array<double, kBuffers> dirtied{};  // the windows' lines dirtied, summed
  for (const UnitFigures& f : figs) {
    run += f.run_compression;
    win += f.window_compression;
    for (size_t b = 0; b < size_t(kBuffers); ++b) dirtied[b] += double(f.window_lines_dirtied_of[b]);
  }
  // Bytes per line written, per surface, over the units' write-backs.
  std::array<double, kBuffers> ratio;
  for (size_t b = 0; b < size_t(kBuffers); ++b)
    ratio[b] = run.bytes_written_uncompressed[b]
                   ? double(run.bytes_written[b]) / double(run.bytes_written_uncompressed[b])
                   : 1.0;
  // Metadata: the windows' metadata lines written (a metadata cache holds a
  // tile's state bits far longer than a window: its lines made dirty before
  // it are written in it), plus the last unit's tail (the final flush).
  auto metadata_written = [](const CompressionTraffic& c) {
    double v = 0;
    for (uint64_t x : c.metadata_bytes_written) v += double(x);
    return v;
  };
  std::vector<double> wr(k);
  for (size_t i = 0; i < k; ++i) {
    const UnitFigures& f = figs[i];
    double y = metadata_written(f.window_compression);
    for (size_t b = 0; b < size_t(kBuffers); ++b) y += double(f.window_lines_dirtied_of[b]) * lb * ratio[b];
    wr[i] = lib.whole ? double(f.window_bytes_written) : y;
  }
  out.dram_bytes_written =
      estimate(wr, double(lib.whole ? figs.back().tail_bytes_written : metadata_written(figs.back().tail_compression)));
  // The traffic: the windows' counts per fragment times N, plus the last
  // unit's tail (its drain and final flush), as the DRAM bytes read.
  double sm = 0;
  for (double v : m) sm += v;
  const double scale = sm > 0 ? double(lib.fragments) / sm : 0.0;
  CompressionTraffic& e = out.stats.compression;
  e = CompressionTraffic{};
  each_count(e, win, [scale](uint64_t& x, const uint64_t& w) { x = uint64_t(std::llround(double(w) * scale)); });
  e += tail;
  out.stats.compression_on = true;
  if (lib.whole) return;
  // Data writes lag the window: by the lines it dirtied instead, in the
  // units' proportions of block sizes.
  for (size_t b = 0; b < size_t(kBuffers); ++b) {
    // A compressed surface the units dirtied: their final flushes wrote it back.
    const bool on = run.lines_written[b] > 0;
    if (!on) continue;
    const double lines = dirtied[b] * scale;
    e.lines_written[b] = uint64_t(std::llround(lines));
    e.bytes_written_uncompressed[b] = uint64_t(std::llround(lines * lb));
    e.bytes_written[b] = uint64_t(std::llround(lines * lb * ratio[b]));
    const double n = double(run.lines_written[b]);
    for (size_t j = 0; j < 4; ++j)
      e.writes_per_class[b][j] = n > 0 ? uint64_t(std::llround(lines * double(run.writes_per_class[b][j]) / n)) : 0;
    e.writes_cleared[b] = n > 0 ? uint64_t(std::llround(lines * double(run.writes_cleared[b]) / n)) : 0;
  }
}

SampledRun run_sampled(const LivePoints& lib, const HwConfig& hw, int jobs) {
  SampledRun out;
  const auto t0 = std::chrono::steady_clock::now();
  const double cpu0 = process_cpu_seconds();
  const size_t k = lib.points.size();
  jobs = int(std::max<size_t>(1, std::min<size_t>(size_t(std::max(jobs, 1)), k)));
  out.jobs = jobs;
  // Every worker builds a unit's pipeline at a time: `jobs` pipelines at
  // once, charged before any is built (memory_estimate.h).
  const MemoryEstimate pipelines = estimate_memory(
      hw, MemoryShape{lib.header.width, lib.header.height, lib.header.spp, lib.method.method, uint32_t(jobs)});
  check_model_memory(hw, pipelines);
  BudgetShare model_memory;
  model_memory.add(pipelines.total_bytes, "the sampled workers' pipelines");
  std::vector<UnitFigures> figs;
  double worker_cpu = 0;
  if (jobs > 1) {
    figs = run_workers(lib, hw, jobs, worker_cpu);
  } else {
    Progress progress("sampled: units", "units");
    for (size_t i = 0; i < k; ++i) {
      figs.push_back(figures_of(simulate_livepoint(lib, i, hw), lib.points[i].fragments.size()));
      progress.update(double(i + 1) / double(k), i + 1);
    }
    progress.finish();
  }
  // Per unit: its window's figures y and its fragments m. The estimate is
  // N (sum y) / (sum m), computed in that order so that one unit over the
  // whole input (lib.whole) gives the full run's figures exactly.
  std::vector<double> cyc(k), rd(k), wr(k), m(k);
  for (size_t i = 0; i < k; ++i) {
    cyc[i] = double(figs[i].window_cycles);
    rd[i] = double(figs[i].window_bytes_read);
    wr[i] = double(figs[i].window_lines_dirtied) * double(hw.cache.line_bytes);
    m[i] = double(lib.points[i].window);
    out.fragments_detailed += figs[i].fragments;
    out.fragments_warmed += figs[i].warming_used;
    out.units_warming_short += figs[i].warming_short;
  }
  const UnitFigures& last = figs.back();
  const double n = double(lib.fragments), t = student_t975(k - 1);
  auto estimate = [&](const std::vector<double>& y, double tail) {
    double sy = 0, sm = 0;
    for (size_t i = 0; i < k; ++i) {
      sy += y[i];
      sm += m[i];
    }
    Estimate e;
    e.value = (sm > 0 ? n * sy / sm : 0.0) + tail;
    // The interval: Student t over the units' figures per fragment.
    double mean = 0, var = 0;
    for (size_t i = 0; i < k; ++i) mean += y[i] / m[i] / double(k);
    for (size_t i = 0; i < k; ++i) var += (y[i] / m[i] - mean) * (y[i] / m[i] - mean);
    var = k > 1 ? var / double(k - 1) : 0.0;
    const double half = k > 1 ? t * n * std::sqrt(var / double(k)) : 0.0;
    e.low = e.value - half;
    e.high = e.value + half;
    return e;
  };
  out.units = k;
  out.total_cycles = estimate(cyc, double(last.tail_cycles));
  out.dram_bytes_read = estimate(rd, double(last.tail_bytes_read));
  // Every dirtied line is written once, at an eviction or the final flush:
  // the flush is already counted by the lines the windows dirtied. Writes
  // applied after a window's last retirement are balanced by the warm-up's
  // applied inside it -- except for a whole-input unit, which has no warm-up:
  // its tail's lines count.
  out.dram_bytes_written =
      estimate(wr, lib.whole ? double(last.tail_lines_dirtied) * double(hw.cache.line_bytes) : 0.0);
  if (last.compression) estimate_compression(lib, hw, figs, m, estimate, out);

  // Activities: each unit instance's share of the units' cycles, over their
  // whole runs, scaled to the estimated total.
  uint64_t all_cycles = 0, all_busy = 0, all_service = 0;
  for (const UnitFigures& f : figs) {
    all_cycles += f.total_cycles;
    all_busy += f.dram_max_channel_busy;
    all_service += f.dram_max_channel_service;
  }
  const double scale = all_cycles ? out.total_cycles.value / double(all_cycles) : 0.0;
  out.units_estimated = figs.front().units;
  for (UnitReport& r : out.units_estimated) r.stats = UnitStats{};
  for (const UnitFigures& f : figs) {
    invariant(f.units.size() == out.units_estimated.size(), "every unit run elaborates the same pipeline");
    for (size_t i = 0; i < f.units.size(); ++i) {
      UnitStats& s = out.units_estimated[i].stats;
      for (int a = 0; a < kActivities; ++a) s.cycles[size_t(a)] += f.units[i].stats.cycles[size_t(a)];
      s.fragments += f.units[i].stats.fragments;
      s.samples += f.units[i].stats.samples;
      s.activations += f.units[i].stats.activations;
    }
  }
  for (UnitReport& r : out.units_estimated)
    for (uint64_t& c : r.stats.cycles) c = uint64_t(std::llround(double(c) * scale));
  CycleStats& s = out.stats;
  s.hw = hw;
  s.total_cycles = uint64_t(std::llround(std::max(0.0, out.total_cycles.value)));
  s.units = out.units_estimated;
  s.dram_utilization = all_cycles ? double(all_busy) / double(all_cycles) : 0.0;
  // The busiest channels' cycles, as the units' activities: their share of
  // the units' cycles times the estimated total.
  s.dram.max_channel_busy = uint64_t(std::llround(double(all_busy) * scale));
  s.dram.max_channel_service = uint64_t(std::llround(double(all_service) * scale));
  s.frame_time_us = double(s.total_cycles) / (hw.clock.frequency_ghz * 1e3);
  s.dram_peak_gbps = double(hw.dram.channels) * hw.dram.bytes_per_clock * hw.clock.frequency_ghz;
  const double bytes = out.dram_bytes_read.value + out.dram_bytes_written.value;
  s.dram_achieved_gbps = s.frame_time_us > 0 ? bytes / (s.frame_time_us * 1e3) : 0.0;
  s.bottleneck = classify_bottleneck(s);
  s.memory_bound = s.bottleneck.kind == Bottleneck::Kind::kBandwidth;

  out.sim_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  out.cpu_seconds = process_cpu_seconds() - cpu0 + worker_cpu;
  return out;
}

Touch touch_of(const FragWork& w, bool slab) {
  Touch t;
  t.x = w.f->x;
  t.y = w.f->y;
  t.covered = w.covered;
  t.reached_write = !w.killed();
  t.written = t.reached_write ? w.written : 0;
  t.slab_kept = t.reached_write && slab && w.slab.kept;
  t.routed = w.route != DrawRoute::kMethod;
  t.reads_colour = t.routed && w.draw && draw_reads_colour(*w.draw);
  t.depth_write = t.routed && t.reached_write && w.depth_written != 0;
  return t;
}

void for_each_touch_line(const Touch& x, const AddressMap& amap, bool tracker, bool slab,
                         const std::function<void(uint64_t, bool, Buffer)>& f) {
  touch_lines(x, amap, tracker, slab, f);
}

}  // namespace ropsim
