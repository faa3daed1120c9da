// Benchmark (not a test): simulated fragments per host second of the cycle
// model at 16 spp on cloth with configs/default.toml (the built-in defaults),
// and its ratio to the functional golden model, both measured in this run on
// the same in-memory trace (target: >= 1 M fragments/s for the cycle model).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "rtl_models/config/hw_config.h"
#include "sim/fidelity/cycle/cycle_run.h"
#include "sim/fidelity/functional/driver.h"
#include "sim/fidelity/sampled/livepoints.h"
#include "util/host_threads.h"

using namespace ropsim;

namespace {

std::string trace_path() {
  static const std::string p = [] {
    const std::string path = "/tmp/ropsim-bench-cloth16.rtr";
    SceneParams s;
    s.name = "cloth";
    s.spp = 16;
    write_scene_trace(s, path);
    return path;
  }();
  return p;
}

void BM_CycleVsFunctional(benchmark::State& state, SorterKind sorter) {
  InputSpec in;
  in.trace_path = trace_path();
  GoldenConfig g;
  HwConfig hw;
  hw.sorter.kind = sorter;
  double cyc_s = 0, fun_s = 0;
  uint64_t frags = 0;
  for (auto _ : state) {
    {
      // The cycle run's final state is freed before the functional run is
      // timed. Held across it, it made the functional run slower on the
      // 2-core VM: 2.4 M fragments/s with the trace decoded on a thread of
      // its own, 3.7 M decoded inline, where a functional run in a process
      // of its own is faster with that thread (docs/trace-format.md
      // "Reader"). Freed, the figure is 4.7-4.8 M fragments/s.
      const CycleRun c = run_cycle(in, g, hw);
      cyc_s += c.wall_seconds;
      frags += c.counters.fragments;
    }
    const auto t0 = std::chrono::steady_clock::now();
    const FunctionalRun f = run_functional(in, g, false, 1);  // one thread, as the cycle model
    fun_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    benchmark::DoNotOptimize(f.counters.samples_written);
  }
  state.counters["cycle_frag_per_s"] = double(frags) / cyc_s;
  state.counters["functional_frag_per_s"] = double(frags) / fun_s;
  state.counters["functional_over_cycle"] = cyc_s / fun_s;
}

// Sampled simulation from live-points (livepoints.h) against the full cycle
// model, on ROPSIM_BENCH_TRACE (default: the cloth trace above) and the design
// configs/<name>.toml: the estimate's error in total cycles and DRAM bytes,
// whether the 95 % interval covers the truth, and the host time of the sampled
// run per design (the library reused) against the full run's, both measured
// here. The library is built once per process (its time: library_s), on all
// cores as `ropsim livepoints` does. The sampled run is timed with one worker
// (sampled_s, speedup_*) and with one per core, as `ropsim run -j` defaults
// to (sampled_cores_s, speedup_*_cores); the cycle model runs on one core
// whatever the host has.
//   ROPSIM_BENCH_TRACE=motor.rtr build/ropsim_bench_cycle --benchmark_filter=Sampled
void BM_SampledVsCycle(benchmark::State& state, const char* design) {
  InputSpec in;
  const char* env = std::getenv("ROPSIM_BENCH_TRACE");
  in.trace_path = env && *env ? env : trace_path();
  static double library_s = 0;
  static const LivePoints lib = [&] {
    const auto t0 = std::chrono::steady_clock::now();
    SamplingParams sp;
    // ROPSIM_BENCH_SAMPLING=U,W,C,K,T[,R] overrides the defaults (unit,
    // warm-up, cool-down, units, tag-only warming, its reach).
    if (const char* v = std::getenv("ROPSIM_BENCH_SAMPLING"))
      std::sscanf(v, "%lu,%lu,%lu,%lu,%lu,%lf", &sp.unit_fragments, &sp.warmup_fragments, &sp.cooldown_fragments,
                  &sp.units, &sp.warming_fragments, &sp.warming_reach);
    LivePoints l = record_livepoints(in, GoldenConfig{}, sp);
    library_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return l;
  }();
  const HwConfig hw = load_hw_config(std::string(ROPSIM_SOURCE_DIR) + "/configs/" + design + ".toml");
  SampledRun s, s_cores;
  CycleRun full;
  double full_s = 0;
  const int cores = available_cores();
  for (auto _ : state) {
    s = run_sampled(lib, hw);
    s_cores = run_sampled(lib, hw, cores);
    const auto t0 = std::chrono::steady_clock::now();
    full = run_cycle(in, GoldenConfig{}, hw);
    full_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  auto err = [](const Estimate& e, double truth) { return 100.0 * (e.value - truth) / truth; };
  auto covered = [](const Estimate& e, double truth) { return e.low <= truth && truth <= e.high ? 1.0 : 0.0; };
  const double cyc = double(full.stats.total_cycles), rd = double(full.stats.dram.total_bytes_read()),
               wr = double(full.stats.dram.total_bytes_written());
  state.counters["cycles_err_pct"] = err(s.total_cycles, cyc);
  state.counters["cycles_covered"] = covered(s.total_cycles, cyc);
  state.counters["read_err_pct"] = err(s.dram_bytes_read, rd);
  state.counters["read_covered"] = covered(s.dram_bytes_read, rd);
  state.counters["written_err_pct"] = err(s.dram_bytes_written, wr);
  state.counters["written_covered"] = covered(s.dram_bytes_written, wr);
  state.counters["detailed_share"] = double(s.fragments_detailed) / double(lib.fragments);
  state.counters["warmed_per_unit"] = double(s.fragments_warmed) / double(s.units);
  state.counters["sampled_s"] = s.sim_seconds;
  state.counters["cycle_s"] = full_s;
  state.counters["library_s"] = library_s;
  state.counters["speedup_per_design"] = full_s / s.sim_seconds;
  state.counters["speedup_with_library"] = full_s / (s.sim_seconds + library_s);
  state.counters["cores"] = cores;
  state.counters["sampled_cores_s"] = s_cores.sim_seconds;
  state.counters["speedup_per_design_cores"] = full_s / s_cores.sim_seconds;
  state.counters["speedup_with_library_cores"] = full_s / (s_cores.sim_seconds + library_s);
}

// The host cost of a waveform (--vcd, waveform.h), all sides in this run on
// the cloth trace above: a 1,000-cycle window (the run stays decoupled), the
// same window in lockstep (what every --vcd run cost before the waveform
// recorded events at their own cycles) and the whole run, each over the run
// without --vcd: sim_ the simulation alone (CycleRun::sim_seconds), wall_ the
// whole run_cycle (writing the file included).
//   build/ropsim_bench_cycle --benchmark_filter=Waveform
void BM_WaveformCost(benchmark::State& state) {
  InputSpec in;
  in.trace_path = trace_path();
  const GoldenConfig g;
  const HwConfig hw;
  const std::string vcd = "/tmp/ropsim-bench-waveform.vcd";
  double sim[4] = {0, 0, 0, 0}, wall[4] = {0, 0, 0, 0};  // plain, window, window in lockstep, whole run
  auto add = [&](int k, const CycleRun& r) {
    sim[k] += r.sim_seconds;
    wall[k] += r.wall_seconds;
  };
  auto with = [&](uint64_t first, uint64_t last, bool lock) {
    CycleOptions o;
    o.vcd_path = vcd;
    o.vcd_first = first;
    o.vcd_last = last;
    o.lockstep = lock;
    return run_cycle(in, g, hw, o);
  };
  for (auto _ : state) {
    add(0, run_cycle(in, g, hw));
    add(1, with(20000, 21000, false));
    add(2, with(20000, 21000, true));
    add(3, with(0, ~uint64_t{0}, false));
  }
  std::remove(vcd.c_str());
  const char* names[4] = {"", "window", "window_lockstep", "whole_run"};
  for (int k = 1; k < 4; ++k) {
    state.counters[std::string("sim_") + names[k] + "_over_plain"] = sim[k] / sim[0];
    state.counters[std::string("wall_") + names[k] + "_over_plain"] = wall[k] / wall[0];
  }
}

// The golden model on all cores against one, on a trace file read as `ropsim
// run` reads it (ROPSIM_BENCH_TRACE, default the cloth trace above; the
// issue's figure is the captured motor at 1920x1080 and 16 spp): each
// iteration runs one thread and then every core, so both sides of a pair
// share the machine's state; speedup_median is the median of the pairs'
// ratios (the machine is noisy), one_s and cores_s their sides' medians.
//   ROPSIM_BENCH_TRACE=motor.rtr build/ropsim_bench_cycle --benchmark_filter=FunctionalThreads
void BM_FunctionalThreads(benchmark::State& state) {
  InputSpec in;
  const char* env = std::getenv("ROPSIM_BENCH_TRACE");
  in.trace_path = env && *env ? env : trace_path();
  const GoldenConfig g;
  const int cores = available_cores();
  std::vector<double> one, all, ratio;
  for (auto _ : state) {
    const FunctionalRun a = run_functional(in, g, false, 1);
    const FunctionalRun b = run_functional(in, g, false, cores);
    benchmark::DoNotOptimize(b.counters.samples_written);
    one.push_back(a.wall_seconds);
    all.push_back(b.wall_seconds);
    ratio.push_back(a.wall_seconds / b.wall_seconds);
  }
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n == 0 ? 0.0 : n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
  };
  state.counters["cores"] = cores;
  state.counters["one_s"] = median(one);
  state.counters["cores_s"] = median(all);
  state.counters["speedup_median"] = median(ratio);
  state.counters["speedup_min"] = *std::min_element(ratio.begin(), ratio.end());
  state.counters["speedup_max"] = *std::max_element(ratio.begin(), ratio.end());
}

}  // namespace

BENCHMARK(BM_FunctionalThreads)->Iterations(9)->Unit(benchmark::kSecond);
BENCHMARK(BM_WaveformCost)->Iterations(5)->Unit(benchmark::kSecond);

// The host cost of compression modelling: the cycle model on cloth at 16 spp
// (lk) with configs/uncompressed.toml and with the default design (depth and
// colour compression, Hi-Z), alternated in one run; compression_cost =
// on / off - 1 of the sc_start time.
void BM_CompressionCost(benchmark::State& state) {
  InputSpec in;
  in.trace_path = trace_path();
  GoldenConfig g;
  const HwConfig off = load_hw_config(std::string(ROPSIM_SOURCE_DIR) + "/configs/uncompressed.toml");
  const HwConfig on;
  g.compression = on.compression.setup();
  double on_s = 0, off_s = 0;
  for (auto _ : state) {
    const CycleRun a = run_cycle(in, g, off);
    const CycleRun b = run_cycle(in, g, on);
    off_s += a.sim_seconds;
    on_s += b.sim_seconds;
    benchmark::DoNotOptimize(b.stats.total_cycles);
  }
  state.counters["off_s"] = off_s / double(state.iterations());
  state.counters["on_s"] = on_s / double(state.iterations());
  state.counters["compression_cost"] = on_s / off_s - 1.0;
}
BENCHMARK(BM_CompressionCost)->Iterations(3)->Unit(benchmark::kSecond);

BENCHMARK_CAPTURE(BM_SampledVsCycle, default, "default")->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK_CAPTURE(BM_SampledVsCycle, narrow, "narrow")->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK_CAPTURE(BM_SampledVsCycle, wide, "wide")->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK_CAPTURE(BM_CycleVsFunctional, bitonic, SorterKind::kBitonic)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_CycleVsFunctional, serial, SorterKind::kSerial)->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
