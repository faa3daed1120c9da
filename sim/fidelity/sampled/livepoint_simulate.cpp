// Simulating one unit of a live-point library: the cycle model restored to
// the unit's state, its caches, compression state and Hi-Z warmed, the
// unit's window run and measured (livepoints.h).
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
#include "rtl_models/top/surface_compression.h"
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
    const SurfaceCompression comp = compress_surfaces(hw, h, *rop);
    if (comp) {
      warm_compression(*comp.model, *comp.tiles, lp, h, hw, amap);
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
      (r.window_compression = cs1) -= cs0;
      (r.tail_compression = r.run_compression) -= cs1;
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

void for_each_touch_line(const Touch& x, const AddressMap& amap, bool tracker, bool slab,
                         const std::function<void(uint64_t, bool, Buffer)>& f) {
  touch_lines(x, amap, tracker, slab, f);
}

}  // namespace ropsim
