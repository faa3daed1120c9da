// Benchmark (not a test): simulated fragments per host second of the cycle
// model at 16 spp on cloth with configs/default.toml (the built-in defaults),
// and its ratio to the functional golden model, both measured in this run on
// the same in-memory trace (target: >= 1 M fragments/s for the cycle model).
#include <benchmark/benchmark.h>

#include <chrono>
#include <string>

#include "cycle_run.h"
#include "driver.h"
#include "hw_config.h"

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
    const CycleRun c = run_cycle(in, g, hw);
    const auto t0 = std::chrono::steady_clock::now();
    const FunctionalRun f = run_functional(in, g, false, 1);  // one thread, as the cycle model
    fun_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    cyc_s += c.wall_seconds;
    frags += c.counters.fragments;
    benchmark::DoNotOptimize(f.counters.samples_written);
  }
  state.counters["cycle_frag_per_s"] = double(frags) / cyc_s;
  state.counters["functional_frag_per_s"] = double(frags) / fun_s;
  state.counters["functional_over_cycle"] = cyc_s / fun_s;
}

}  // namespace

BENCHMARK_CAPTURE(BM_CycleVsFunctional, bitonic, SorterKind::kBitonic)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_CycleVsFunctional, serial, SorterKind::kSerial)->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
