// Recording a live-point library: the golden model runs the whole input
// once and keeps, for each unit, the state before it, its fragments, the
// touches the warming replays and the tiles it writes (livepoints.h).
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
#include "sim/fidelity/sampled/livepoints.h"
#include "util/byte_codec.h"
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

}  // namespace ropsim
