// Golden-model throughput (covered samples per second on one core) and the
// memory of a large sparse screen. Run: scripts/bench.sh
#include <benchmark/benchmark.h>

#include <map>

#include "rtl_models/golden/golden_model.h"
#include "sim/fidelity/functional/driver.h"
#include "traces/raster/sample_patterns.h"

using namespace ropsim;

namespace {

const FragmentList& cloth(int spp) {
  static std::map<int, FragmentList> cache;
  auto it = cache.find(spp);
  if (it == cache.end()) {
    InputSpec in;
    in.scene.name = "cloth";
    in.scene.spp = spp;
    it = cache.emplace(spp, load_fragments(in)).first;
  }
  return it->second;
}

void BM_Golden(benchmark::State& state, Method method) {
  const int spp = int(state.range(0));
  const FragmentList& fl = cloth(spp);
  GoldenConfig cfg;
  cfg.method = method;
  uint64_t samples = 0;
  for (auto _ : state) {
    auto m = make_functional_model(fl.header, cfg);
    for (int pass = 0; pass < m->passes(); ++pass) {  // a multi-pass method replays the input per pass
      m->begin_pass(pass);
      for (const Fragment& f : fl.fragments) m->draw(f);
    }
    samples += m->counters().samples_tested / uint64_t(m->passes());  // the input's covered samples, once
    benchmark::DoNotOptimize(m->counters().samples_written);
  }
  state.counters["samples_per_s"] = benchmark::Counter(double(samples), benchmark::Counter::kIsRate);
  state.counters["fragments_per_s"] =
      benchmark::Counter(double(fl.fragments.size()) * double(state.iterations()), benchmark::Counter::kIsRate);
}

// The golden model on state.range(1) host threads (--threads), cloth
// fragments in memory, drawn in the driver's batches of 4096: the speed-up
// over one thread is the ratio of the /1 and /2 rows of one run. The work is
// the same on every thread count (the lanes' bits are identical).
void BM_GoldenThreads(benchmark::State& state, Method method) {
  const int spp = int(state.range(0)), threads = int(state.range(1));
  const FragmentList& fl = cloth(spp);
  GoldenConfig cfg;
  cfg.method = method;
  uint64_t samples = 0;
  constexpr size_t kBatch = 4096;
  for (auto _ : state) {
    auto m = make_functional_model(fl.header, cfg, threads);
    for (int pass = 0; pass < m->passes(); ++pass) {
      m->begin_pass(pass);
      for (size_t i = 0; i < fl.fragments.size(); i += kBatch)
        m->draw_batch(fl.fragments.data() + i, std::min(kBatch, fl.fragments.size() - i));
    }
    const Counters c = m->counters();
    samples += c.samples_tested / uint64_t(m->passes());
    benchmark::DoNotOptimize(c.samples_written);
  }
  state.counters["samples_per_s"] = benchmark::Counter(double(samples), benchmark::Counter::kIsRate);
  state.counters["fragments_per_s"] =
      benchmark::Counter(double(fl.fragments.size()) * double(state.iterations()), benchmark::Counter::kIsRate);
}

// The whole `ropsim run --scene cloth` path: scene rasterized on the fly,
// model, resolve.
void BM_RunScene(benchmark::State& state) {
  InputSpec in;
  in.scene.name = "cloth";
  in.scene.spp = int(state.range(0));
  GoldenConfig cfg;
  uint64_t samples = 0;
  for (auto _ : state) samples += run_functional(in, cfg, false, 1).counters.samples_tested;  // one thread
  state.counters["samples_per_s"] = benchmark::Counter(double(samples), benchmark::Counter::kIsRate);
}

// 3840 x 2160 at 64 spp, 10 % of the screen touched by one full-coverage
// fragment per pixel: peak resident memory of the process.
void BM_Memory4k64(benchmark::State& state) {
  TraceHeader h;
  h.width = 3840;
  h.height = 2160;
  h.spp = 64;
  h.positions = standard_sample_positions(64);
  GoldenConfig cfg;
  for (auto _ : state) {
    auto m = make_functional_model(h, cfg);
    Fragment f;
    f.coverage = ~0ull;
    f.z0 = 0.5f;
    f.alpha = 0.5f;
    f.rgb = {1, 1, 1};
    for (uint32_t y = 972; y < 972 + 216; ++y)
      for (uint32_t x = 0; x < 3840; ++x) {
        f.x = uint16_t(x);
        f.y = uint16_t(y);
        m->draw(f);
      }
    Image img = m->resolve();
    benchmark::DoNotOptimize(img.at(0, 0));
    state.counters["state_MiB"] = double(m->state_bytes()) / (1 << 20);
  }
  state.counters["peak_rss_MiB"] = double(peak_rss_bytes()) / (1 << 20);
}

}  // namespace

BENCHMARK_CAPTURE(BM_Golden, lk, Method::kLk)->Arg(16)->Arg(64)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Golden, enderton, Method::kEnderton)->Arg(16)->Arg(64)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Golden, opaque, Method::kOpaque)->Arg(16)->Arg(64)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Golden, hashed, Method::kHashed)->Arg(16)->Arg(64)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Golden, hashed_a2c, Method::kHashedA2c)->Arg(16)->Arg(64)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Golden, slab, Method::kSlab)->Arg(16)->Arg(64)->Unit(benchmark::kMillisecond);
// The methods with blend passes (docs/methods.md), at 16 spp beside lk's:
// samples_per_s counts the input's covered samples once, so a method of k
// passes should be about k times slower.
BENCHMARK_CAPTURE(BM_Golden, wboit, Method::kWboit)->Arg(16)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Golden, lk_ac, Method::kLkAc)->Arg(16)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Golden, lk_depth, Method::kLkDepth)->Arg(16)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Golden, lk_depth_ac, Method::kLkDepthAc)->Arg(16)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Golden, enderton_ac, Method::kEndertonAc)->Arg(16)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Golden, enderton_depth, Method::kEndertonDepth)->Arg(16)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Golden, enderton_depth_ac, Method::kEndertonDepthAc)->Arg(16)->Unit(benchmark::kMillisecond);
// Wall time (the threads' CPU time is not the point): --benchmark_filter=GoldenThreads
BENCHMARK_CAPTURE(BM_GoldenThreads, lk, Method::kLk)
    ->Args({16, 1})
    ->Args({16, 2})
    ->Args({64, 1})
    ->Args({64, 2})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_GoldenThreads, enderton, Method::kEnderton)
    ->Args({16, 1})
    ->Args({16, 2})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RunScene)->Arg(16)->Arg(64)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Memory4k64)->Iterations(1)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
