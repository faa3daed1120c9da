// The sampled fidelity's estimate: where the units fall, each unit run in
// a worker process, and the figures of the whole input with their 95 %
// intervals (livepoints.h).
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

/// The message a worker writes per unit (util/byte_codec.h).
std::string encode_figures(uint64_t unit, const UnitFigures& f) {
  std::string m;
  ByteWriter w(m);
  for (uint64_t v : {unit, f.window_cycles, f.window_bytes_read, f.window_lines_dirtied, f.tail_cycles,
                     f.tail_bytes_read, f.total_cycles, f.dram_max_channel_busy, f.dram_max_channel_service,
                     f.fragments, f.warming_used, f.warming_short})
    w.u64(v);
  w.u64(f.units.size());
  for (const UnitReport& u : f.units) {
    w.str(u.name);
    w.str(u.kind);
    w.u64(uint64_t(int64_t(u.rop)));
    for (uint64_t c : u.stats.cycles) w.u64(c);
    w.u64(u.stats.fragments);
    w.u64(u.stats.samples);
    w.u64(u.stats.activations);
  }
  for (uint64_t v : {f.window_bytes_written, f.tail_bytes_written, f.compression}) w.u64(v);
  for (const CompressionTraffic* c : {&f.window_compression, &f.tail_compression, &f.run_compression})
    CompressionTraffic::for_each_count(*c, *c, [&w](const uint64_t& v, const uint64_t&) { w.u64(v); });
  for (uint64_t v : f.window_lines_dirtied_of) w.u64(v);
  return m;
}

UnitFigures decode_figures(const std::string& m, uint64_t& unit) {
  ByteReader r(m, "a worker's message holds every figure of its unit");
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
    CompressionTraffic::for_each_count(*c, *c, [&r](uint64_t& v, uint64_t&) { v = r.u64(); });
  for (uint64_t& v : f.window_lines_dirtied_of) v = r.u64();
  invariant(r.done(), "a worker's message ends with its unit's figures");
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
  CompressionTraffic::for_each_count(
      e, win, [scale](uint64_t& x, const uint64_t& w) { x = uint64_t(std::llround(double(w) * scale)); });
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

}  // namespace ropsim
