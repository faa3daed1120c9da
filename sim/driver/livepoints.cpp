#include "livepoints.h"

#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <set>
#include <utility>

#include "address_map.h"
#include "distributor.h"
#include "errors.h"
#include "functional_rop.h"
#include "line_set.h"
#include "rop_pipeline.h"
#include "sim_context.h"

namespace ropsim {

LivePoints record_livepoints(const InputSpec& in, const MethodConfig& method, const SamplingParams& p) {
  if (method.method == Method::kReference) throw UserError("sampled: the reference method has no ROP pipeline");
  if (passes_of(method.method).count != 1 || has_blend_pass(method.method))
    throw UserError(std::string("sampled simulation runs single-pass methods without blend targets; ") +
                    to_string(method.method) + " is not one");
  if (p.unit_fragments == 0 || p.units == 0) throw UserError("sampled: the unit size and the unit count must be >= 1");
  LivePoints lib;
  lib.method = method;
  lib.params = p;
  {  // N: the sampling design needs the input's length
    auto src = open_fragments(in);
    for (Fragment f; src->next(f);) ++lib.fragments;
  }
  auto src = open_fragments(in);
  lib.header = src->header();
  const uint64_t n = lib.fragments;
  const uint64_t u = std::min<uint64_t>(p.unit_fragments, std::max<uint64_t>(n, 1));
  const uint64_t k_units = std::max<uint64_t>(1, std::min<uint64_t>(p.units, n / u));
  const uint64_t period = n / k_units;  // >= u
  lib.params.unit_fragments = u;
  lib.params.units = k_units;
  // Window k starts at n - u - (K - 1 - k) period: the last one ends the input.
  // Each but the last has C fragments of cool-down after it, within the
  // period (the recording reads a live-point's fragments once).
  const uint64_t cool = std::min<uint64_t>(p.cooldown_fragments, period - u);
  std::vector<uint64_t> starts(k_units), firsts(k_units), ends(k_units);
  uint64_t prev_end = 0;
  for (uint64_t k = 0; k < k_units; ++k) {
    starts[k] = n - u - (k_units - 1 - k) * period;
    firsts[k] = starts[k] - std::min<uint64_t>(p.warmup_fragments, starts[k] - prev_end);
    ends[k] = starts[k] + u + (k + 1 < k_units ? cool : 0);
    prev_end = ends[k];
  }
  lib.params.cooldown_fragments = cool;

  FunctionalRop rop(lib.header, method);
  FragWork w;
  uint64_t i = 0;
  size_t k = 0;
  Fragment f;
  // The last T fragments' touches, a ring.
  const size_t ring_size = size_t(std::min<uint64_t>(p.warming_fragments, n));
  std::vector<Touch> ring(ring_size);
  size_t ring_at = 0, ring_fill = 0;
  auto touched = [&](const Fragment& x) {
    if (ring_size == 0) return;
    Touch& t = ring[ring_at];
    t.x = x.x;
    t.y = x.y;
    t.covered = w.covered;
    t.reached_write = !w.killed();
    t.written = t.reached_write ? w.written : 0;
    t.slab_kept = t.reached_write && method.method == Method::kSlab && w.slab.kept;
    ring_at = (ring_at + 1) % ring_size;
    ring_fill = std::min(ring_fill + 1, ring_size);
  };
  for (;;) {
    if (k < k_units && i == firsts[k]) {
      LivePoint lp;
      lp.first = firsts[k];
      lp.warmup = starts[k] - firsts[k];
      lp.window = u;
      const uint64_t count = ends[k] - firsts[k];
      lp.fragments.reserve(count);
      while (lp.fragments.size() < count && src->next(f)) lp.fragments.push_back(f);
      invariant(lp.fragments.size() == count, "the input delivers the fragments it was counted with");
      const SampleStore& st = rop.store();
      lp.pre = std::make_unique<SampleStore>(lib.header, st.has_tracker(), st.targets());
      std::set<std::pair<uint32_t, uint32_t>> tiles;
      for (const Fragment& x : lp.fragments)
        if (tiles.emplace(x.x >> 3, x.y >> 3).second) lp.pre->copy_tile_from(st, x.x, x.y);
      lp.warming.reserve(ring_fill);
      for (size_t j = 0; j < ring_fill; ++j)
        lp.warming.push_back(ring[(ring_at + ring_size - ring_fill + j) % ring_size]);
      for (const Fragment& x : lp.fragments) {
        w.f = &x;
        rop.process(w);
        touched(x);
      }
      i += count;
      ++k;
      lib.points.push_back(std::move(lp));
      continue;
    }
    if (!src->next(f)) break;
    w.f = &f;
    rop.process(w);
    touched(f);
    ++i;
  }
  invariant(k == k_units && i == n, "every live-point is recorded in one pass over the input");
  lib.counters = rop.counters();
  lib.image = rop.resolve();
  return lib;
}

UnitRun simulate_livepoint(const LivePoints& lib, size_t unit, const HwConfig& hw) {
  invariant(unit < lib.points.size(), "simulate_livepoint is given one of the library's units");
  const LivePoint& lp = lib.points[unit];
  const TraceHeader& h = lib.header;
  auto rop = std::make_unique<FunctionalRop>(h, lib.method);
  LineSet in_dram(hw.cache.line_bytes);
  const AddressMap amap(h.width, h.spp, rop->setup().tracker_bytes, hw.cache.line_bytes, lib.method.formats,
                        rop->setup().slab_bytes);
  const bool tracker = rop->store().has_tracker(), slab = rop->store().has_slab();
  auto insert = [&in_dram](uint64_t line) { in_dram.insert(line); };
  // The clear values, from a tile allocated cleared.
  SampleStore cleared(h, tracker, rop->store().targets());
  const PixelRef clear = cleared.pixel(0, 0);
  lp.pre->tile_map().for_each([&](uint32_t x0, uint32_t y0, const SampleTile&) {
    rop->store().copy_tile_from(*lp.pre, x0, y0);
    // A line that holds a written value is taken to be in DRAM (see livepoints.h).
    for (int p = 0; p < 64; ++p) {
      const uint32_t x = x0 + uint32_t(p & 7), y = y0 + uint32_t(p >> 3);
      if (x >= h.width || y >= h.height) continue;
      const PixelView v = lp.pre->view(x, y);
      uint64_t written = 0;
      for (int i = 0; i < h.spp; ++i)
        if (std::memcmp(&v.depth[i], &clear.depth[0], sizeof(float)) != 0 ||
            std::memcmp(&v.rgb[3 * i], &clear.rgb[0], 3 * sizeof(uint16_t)) != 0)
          written |= uint64_t{1} << i;
      if (written) {
        amap.for_each_sample_line(Buffer::kDepth, x, y, written, insert);
        amap.for_each_sample_line(Buffer::kColor, x, y, written, insert);
      }
      if (tracker && !(*v.tracker == TrackerState{})) amap.for_each_tracker_line(x, y, insert);
      if (slab && v.slab->count > 0) amap.for_each_layer_line(x, y, insert);
    }
  });

  UnitRun r;
  const uint64_t warm = lp.warmup, end = lp.warmup + lp.window, all = lp.fragments.size();
  uint64_t retired = 0, c0 = 0, c1 = 0, w0 = 0, w1 = 0;
  DramStats d0, d1;
  {
    FreshSimContext sim;
    auto top = std::make_unique<RopPipeline>("unit", fragments_from(h, lp.fragments), *rop, in_dram, hw);
    top->set_decoupled(true);
    RopPipeline* t = top.get();
    // Tag-only warming: the T fragments before the warm-up, in order, through
    // the caches of the ROPs that own their pixels (depth test reads, then
    // the writeback's writes).
    const RopOwnership owner(hw.distributor, h.width);
    for (const Touch& x : lp.warming) {
      RopCache& c = *t->caches()[owner.rop_of(x.x, x.y)];
      if (slab) {
        amap.for_each_layer_line(x.x, x.y, [&](uint64_t l) { c.warm(l, false, Buffer::kLayers); });
        if (x.slab_kept) amap.for_each_layer_line(x.x, x.y, [&](uint64_t l) { c.warm(l, true, Buffer::kLayers); });
        continue;
      }
      amap.for_each_sample_line(Buffer::kDepth, x.x, x.y, x.covered,
                                [&](uint64_t l) { c.warm(l, false, Buffer::kDepth); });
      if (tracker) amap.for_each_tracker_line(x.x, x.y, [&](uint64_t l) { c.warm(l, false, Buffer::kTracker); });
      if (!x.reached_write) continue;
      amap.for_each_sample_line(Buffer::kDepth, x.x, x.y, x.written,
                                [&](uint64_t l) { c.warm(l, true, Buffer::kDepth); });
      amap.for_each_sample_line(Buffer::kColor, x.x, x.y, x.written,
                                [&](uint64_t l) { c.warm(l, true, Buffer::kColor); });
      if (tracker) amap.for_each_tracker_line(x.x, x.y, [&](uint64_t l) { c.warm(l, true, Buffer::kTracker); });
    }
    auto dirtied = [t] {
      uint64_t n = 0;
      for (const auto& c : t->caches()) n += c->stats().dirtied;
      return n;
    };
    w0 = dirtied();  // (warming counts nothing; a unit without warm-up measures from here)
    t->retirement().hook = [&, t](const FragToken&, uint64_t cycle) {
      ++retired;
      if (retired == warm) {
        c0 = cycle;
        d0 = t->dram().stats();
        w0 = dirtied();
      }
      if (retired == end) {
        c1 = cycle;
        d1 = t->dram().stats();
        w1 = dirtied();
      }
    };
    top->run();
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
  }
  r.state = std::make_unique<SampleStore>(std::move(rop->store()));
  return r;
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

SampledRun run_sampled(const LivePoints& lib, const HwConfig& hw) {
  SampledRun out;
  const auto t0 = std::chrono::steady_clock::now();
  const size_t k = lib.points.size();
  std::vector<double> cyc(k), rd(k), wr(k);
  UnitRun last;
  for (size_t i = 0; i < k; ++i) {
    UnitRun r = simulate_livepoint(lib, i, hw);
    const double u = double(lib.params.unit_fragments);
    cyc[i] = double(r.window_cycles) / u;
    rd[i] = double(r.window_bytes_read) / u;
    wr[i] = double(r.window_lines_dirtied) * double(hw.cache.line_bytes) / u;
    out.fragments_detailed += lib.points[i].fragments.size();
    if (i + 1 == k) last = std::move(r);
  }
  const double n = double(lib.fragments), t = student_t975(k - 1);
  auto estimate = [&](const std::vector<double>& v, double tail) {
    double mean = 0, var = 0;
    for (double x : v) mean += x;
    mean /= double(v.size());
    for (double x : v) var += (x - mean) * (x - mean);
    var = v.size() > 1 ? var / double(v.size() - 1) : 0.0;
    Estimate e;
    e.value = n * mean + tail;
    const double half = v.size() > 1 ? t * n * std::sqrt(var / double(v.size())) : 0.0;
    e.low = e.value - half;
    e.high = e.value + half;
    return e;
  };
  out.units = k;
  out.total_cycles = estimate(cyc, double(last.tail_cycles));
  out.dram_bytes_read = estimate(rd, double(last.tail_bytes_read));
  // Every dirtied line is written once, at an eviction or the final flush:
  // the flush is already counted by the lines the windows dirtied.
  out.dram_bytes_written = estimate(wr, 0.0);
  out.sim_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace ropsim
