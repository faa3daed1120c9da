// The pipeline's units, each alone between a scripted source and a sink
// (latency at its boundary, throughput), the pixel-ordering guarantee, the
// sorter networks, and timing that behaves like hardware.
#include "tests/cycle_test_util.h"

using namespace ropsim;
using namespace cycle_test;

// ------------------------------------------------------------ units alone

namespace {

/// Scripted source: pushes the given tokens at the given cycles.
class ScriptSource : public Unit {
 public:
  ScriptSource(const sc_core::sc_module_name& n, const Clock& clk, TokenFifo& out,
               std::vector<std::pair<uint64_t, FragToken*>> script)
      : Unit(n, clk), out_(out), script_(std::move(script)) {}
  void start_of_simulation() override { wake_at(script_.empty() ? 0 : script_[0].first); }

 protected:
  void step(uint64_t now) override {
    while (i_ < script_.size() && script_[i_].first <= now && out_.can_push(now))
      out_.push(script_[i_++].second, now, now + 1);
    if (i_ < script_.size())
      wake_at(std::max(now + 1, script_[i_].first));
    else if (!out_.closed())
      out_.close(now);
  }

 private:
  TokenFifo& out_;
  std::vector<std::pair<uint64_t, FragToken*>> script_;
  size_t i_ = 0;
};

/// Sink: pops every entry the cycle it becomes visible and records the cycle.
class RecordSink : public Unit {
 public:
  RecordSink(const sc_core::sc_module_name& n, const Clock& clk, TokenFifo& in) : Unit(n, clk), in_(in) {}
  std::vector<uint64_t> seen;

 protected:
  void step(uint64_t now) override {
    if (in_.can_pop(now)) {
      in_.pop(now);
      seen.push_back(now);
    }
    if (!in_.empty()) wake_at(std::max(now + 1, in_.head_visible()));
  }

 private:
  TokenFifo& in_;
};

/// A harness around one unit: the source pushes (so the unit sees) tokens at
/// the given cycles; returns the cycles the sink saw outputs at.
struct Harness {
  FreshSimContext sim;
  Clock clk{1.0};
  Scheduler sched{"sched", clk};
  TraceHeader header;
  FunctionalRop rop;
  TokenPool pool;
  Retirement retirement{pool};
  AddressMap amap;
  std::unique_ptr<TokenFifo> in, out;
  Harness(int spp, Method m)
      : header(small_header(spp)),
        rop(header, method_config(m)),
        amap(header.width, header.spp, rop.setup().tracker_bytes, 64) {
    in = std::make_unique<TokenFifo>("in", 1024, clk);
    out = std::make_unique<TokenFifo>("out", 1024, clk);
  }
  /// Tokens at pixel (i, 0) with all samples covered and surviving.
  std::vector<std::pair<uint64_t, FragToken*>> tokens(const std::vector<uint64_t>& cycles, int spp) {
    std::vector<std::pair<uint64_t, FragToken*>> v;
    for (size_t i = 0; i < cycles.size(); ++i) {
      FragToken* t = pool.get();
      t->fragment = Fragment{};
      t->fragment.x = uint16_t(i % 64);
      t->fragment.coverage = spp == 64 ? ~0ull : (1ull << spp) - 1;
      t->fragment.alpha = 0.5f;
      t->seq = i;
      t->pixel_key = i;
      rop.fetch(*t);
      t->survivors = t->fragment.coverage;
      t->m = uint32_t(spp);
      t->lk.track = TrackResult{};
      for (int s = 0; s < spp; ++s) t->lk.order[s] = uint8_t(s);
      v.emplace_back(cycles[i], t);
    }
    return v;
  }
};

/// Every UnitAlone test runs each unit in lockstep and decoupled (unit.h):
/// the cycles at its boundary must not change.
bool g_decoupled = false;

/// Runs unit U between a script source (tokens visible at `cycles`) and a sink.
template <class MakeUnit>
std::vector<uint64_t> run_alone(Harness& h, const std::vector<uint64_t>& push_cycles, int spp, MakeUnit make) {
  ScriptSource src("src", h.clk, *h.in, h.tokens(push_cycles, spp));
  auto unit = make(*h.in, *h.out);
  unit->set_decoupled(g_decoupled);
  RecordSink sink("sink", h.clk, *h.out);
  h.in->connect(&src, unit.get());
  h.out->connect(unit.get(), &sink);
  sc_core::sc_start();
  return sink.seen;
}

std::vector<uint64_t> back_to_back(size_t n) {
  std::vector<uint64_t> v(n, 0);
  return v;
}

}  // namespace

// A token pushed by the source at cycle 0 is visible to the unit at cycle 1;
// the unit's output must appear at 1 + L, not at L (nothing at L - 1 after entry).
TEST(UnitAlone, CoverageTrackerLatencyAndThroughput) {
  for (bool decoupled : {false, true}) {
    g_decoupled = decoupled;
    SCOPED_TRACE(decoupled ? "decoupled" : "lockstep");
    for (uint32_t L : {1u, 3u, 7u}) {
      Harness h(4, Method::kLk);
      HwConfig::Tracker cfg;
      cfg.latency_cycles = L;
      const auto seen = run_alone(h, back_to_back(50), 4, [&](TokenFifo& in, TokenFifo& out) {
        return std::make_unique<CoverageTracker>("tracker", h.clk, h.rop, cfg, in, out);
      });
      ASSERT_EQ(seen.size(), 50u);
      EXPECT_EQ(seen[0], 1 + L) << "first output must appear exactly L = " << L << " cycles after entry";
      for (size_t i = 1; i < seen.size(); ++i)
        EXPECT_EQ(seen[i], seen[i - 1] + 1) << "fully pipelined: one fragment per clock (L = " << L << ")";
    }
  }
}

TEST(UnitAlone, SorterVariantsLatencyAndInterval) {
  for (bool decoupled : {false, true}) {
    g_decoupled = decoupled;
    SCOPED_TRACE(decoupled ? "decoupled" : "lockstep");
    struct Case {
      SorterKind kind;
      int spp;
      uint64_t latency, interval;
    };
    // bitonic: log2 N (log2 N + 1) / 2 stages; rank: 1; serial: m clocks, not pipelined.
    for (const Case c : {Case{SorterKind::kBitonic, 16, 10, 1}, Case{SorterKind::kBitonic, 64, 21, 1},
                         Case{SorterKind::kBitonic, 4, 3, 1}, Case{SorterKind::kRank, 16, 1, 1},
                         Case{SorterKind::kSerial, 16, 16, 16}, Case{SorterKind::kSerial, 4, 4, 4}}) {
      Harness h(c.spp, Method::kLk);
      const auto seen = run_alone(h, back_to_back(20), c.spp, [&](TokenFifo& in, TokenFifo& out) {
        return std::make_unique<SampleSorter>("sorter", h.clk, h.rop, make_sorter(c.kind, c.spp), in, out);
      });
      ASSERT_EQ(seen.size(), 20u);
      EXPECT_EQ(seen[0], 1 + c.latency) << to_string(c.kind) << " N=" << c.spp << ": latency";
      for (size_t i = 1; i < seen.size(); ++i)
        EXPECT_EQ(seen[i] - seen[i - 1], c.interval) << to_string(c.kind) << " N=" << c.spp << ": initiation interval";
    }
  }
}

TEST(UnitAlone, AlphaRefGenLanesAndDepth) {
  for (bool decoupled : {false, true}) {
    g_decoupled = decoupled;
    SCOPED_TRACE(decoupled ? "decoupled" : "lockstep");
    struct Case {
      uint32_t lanes, depth;
      int spp;
    };
    for (const Case c : {Case{16, 4, 16}, Case{4, 4, 16}, Case{1, 2, 4}, Case{64, 6, 64}}) {
      Harness h(c.spp, Method::kLk);
      HwConfig::AlphaRef cfg;
      cfg.lanes = c.lanes;
      cfg.pipeline_depth = c.depth;
      const auto seen = run_alone(h, back_to_back(20), c.spp, [&](TokenFifo& in, TokenFifo& out) {
        return std::make_unique<AlphaRefGen>("alpha_ref", h.clk, h.rop, cfg, in, out);
      });
      const uint64_t interval = (uint64_t(c.spp) + c.lanes - 1) / c.lanes;
      ASSERT_EQ(seen.size(), 20u);
      EXPECT_EQ(seen[0], 1 + c.depth + interval - 1) << c.spp << " refs on " << c.lanes << " lanes, depth " << c.depth;
      for (size_t i = 1; i < seen.size(); ++i)
        EXPECT_EQ(seen[i] - seen[i - 1], interval) << c.spp << " refs on " << c.lanes << " lanes";
    }
  }
}

TEST(UnitAlone, DepthTestHitLatencyPlusCompareLatency) {
  for (bool decoupled : {false, true}) {
    g_decoupled = decoupled;
    SCOPED_TRACE(decoupled ? "decoupled" : "lockstep");
    for (uint32_t hit : {1u, 5u})
      for (uint32_t L : {1u, 4u}) {
        Harness h(16, Method::kOpaque);
        HwConfig::DepthTest cfg;
        cfg.latency_cycles = L;
        HwConfig::Cache cc;
        cc.hit_latency_cycles = hit;
        Dram dram{HwConfig::Dram{}};
        LineSet in_dram{64};
        RopCache cache(cc, dram, in_dram);
        // Depth test needs real fragments: a plane at depth 0.5 over cleared pixels.
        const auto seen = run_alone(h, back_to_back(40), 16, [&](TokenFifo& in, TokenFifo& out) {
          return std::make_unique<DepthTest>("depth", h.clk, h.rop, h.retirement, h.amap, cfg, cache, in, out);
        });
        ASSERT_EQ(seen.size(), 40u);
        // Cleared lines come from fast clear at hit latency: entry 1, data at 1 + hit, out at 1 + hit + L.
        EXPECT_EQ(seen[0], 1 + hit + L) << "hit latency " << hit << ", compare latency " << L;
        for (size_t i = 1; i < seen.size(); ++i)
          EXPECT_EQ(seen[i] - seen[i - 1], 1u) << "16 samples at 16 per clock: one fragment per clock";
      }
  }
}

TEST(UnitAlone, DepthTestSamplesPerClockSetsTheInterval) {
  for (bool decoupled : {false, true}) {
    g_decoupled = decoupled;
    SCOPED_TRACE(decoupled ? "decoupled" : "lockstep");
    Harness h(16, Method::kOpaque);
    HwConfig::DepthTest cfg;
    cfg.samples_per_clock = 4;
    Dram dram{HwConfig::Dram{}};
    LineSet in_dram{64};
    RopCache cache(HwConfig::Cache{}, dram, in_dram);
    const auto seen = run_alone(h, back_to_back(10), 16, [&](TokenFifo& in, TokenFifo& out) {
      return std::make_unique<DepthTest>("depth", h.clk, h.rop, h.retirement, h.amap, cfg, cache, in, out);
    });
    ASSERT_EQ(seen.size(), 10u);
    for (size_t i = 1; i < seen.size(); ++i) EXPECT_EQ(seen[i] - seen[i - 1], 4u) << "16 samples / 4 per clock";
  }
}

// The blend unit retires a fragment latency_cycles after it takes it (it has
// no output FIFO: the pixel leaves the scoreboard), and takes one fragment
// every ceil(samples / samples_per_clock) clocks. Tokens pushed at cycle 0
// are visible at 1, so the first retires at 1 + L, never at L.
TEST(UnitAlone, BlendUnitLatencyAndSamplesPerClock) {
  struct NoScoreboard : PixelRelease {
    void release(uint64_t, uint64_t) override {}
  };
  for (bool decoupled : {false, true})
    for (uint32_t L : {1u, 4u})
      for (uint32_t per_clock : {16u, 4u}) {
        SCOPED_TRACE(std::string(decoupled ? "decoupled" : "lockstep") + " L " + std::to_string(L) + " per clock " +
                     std::to_string(per_clock));
        Harness h(16, Method::kWboit);
        NoScoreboard board;
        h.retirement.attach(0, &board);
        std::vector<uint64_t> retired;
        h.retirement.hook = [&](const FragToken&, uint64_t c) { retired.push_back(c); };
        HwConfig::Blend cfg;
        cfg.latency_cycles = L;
        cfg.samples_per_clock = per_clock;
        Dram dram{HwConfig::Dram{}};
        LineSet in_dram{64};
        RopCache cache(HwConfig::Cache{}, dram, in_dram);
        auto toks = h.tokens(back_to_back(12), 16);
        for (auto& [cycle, t] : toks)
          for (int s = 0; s < 16; ++s) t->z[s] = 0.5f;
        ScriptSource src("src", h.clk, *h.in, toks);
        BlendUnit unit("blend", h.clk, h.rop, h.retirement, h.amap, cfg, cache, *h.in);
        unit.set_decoupled(decoupled);
        h.in->connect(&src, &unit);
        sc_core::sc_start();
        ASSERT_EQ(retired.size(), 12u);
        EXPECT_EQ(retired[0], 1 + L) << "the first fragment retires at entry + latency";
        for (size_t i = 1; i < retired.size(); ++i)
          EXPECT_EQ(retired[i] - retired[i - 1], 16 / per_clock) << "16 samples at " << per_clock << " per clock";
        EXPECT_EQ(h.rop.counters().samples_blended, 12u * 16) << "every sample blended";
      }
}

// ------------------------------------------------------------ pixel ordering

TEST(PixelOrderingUnit, SamePixelNeverReordersWhileOthersOvertake) {
  // A 4 x 4 screen at 1 spp: 16 pixels, hundreds of fragments, so nearly every
  // fragment has an earlier one of its pixel in flight. Without fast clear and
  // with a one-way 1 KB cache, memory latencies vary from fragment to fragment,
  // which is what lets fragments overtake.
  TraceHeader h = small_header(1);
  h.width = 4;
  h.height = 4;
  const std::string path = ::testing::TempDir() + "/ordering.rtr";
  {
    TraceWriter w(path, h);
    std::mt19937 rng(7);
    for (uint32_t i = 0; i < 600; ++i) {
      Fragment f;
      f.x = uint16_t(rng() % 4);
      f.y = uint16_t(rng() % 4);
      f.coverage = 1;
      f.z0 = float(rng() % 1000) / 1000.0f;
      f.alpha = 0.5f;
      f.rgb = {float(i % 7) / 7, 0.5f, 1.0f};
      f.prim_id = i;
      w.write(f);
    }
    w.finish();
  }
  HwConfig hw;
  for (const char* a :
       {"cache.fast_clear=false", "cache.size_bytes=1024", "cache.ways=1", "cache.line_bytes=16", "dram.row_bytes=64",
        "dram.interleave_bytes=16", "distributor.rop_units=1", "ordering.window=16"})
    apply_hw_override(hw, a);
  InputSpec in;
  in.trace_path = path;
  std::map<uint64_t, uint64_t> last_seq;  // pixel -> last retired seq
  std::vector<uint64_t> retire_order;
  bool reordered_within_pixel = false;
  CycleOptions opt;
  opt.retire_hook = [&](const FragToken& t, uint64_t) {
    auto it = last_seq.find(t.pixel_key);
    if (it != last_seq.end() && it->second > t.seq) reordered_within_pixel = true;
    last_seq[t.pixel_key] = t.seq;
    retire_order.push_back(t.seq);
  };
  const CycleRun run = run_cycle(in, method_config(Method::kLk), hw, opt);
  ASSERT_EQ(retire_order.size(), 600u);
  EXPECT_FALSE(reordered_within_pixel) << "two fragments of one pixel retired out of trace order";
  EXPECT_FALSE(std::is_sorted(retire_order.begin(), retire_order.end()))
      << "the trace was built so fragments of other pixels overtake; none did, so the test proves nothing";
  // And the image is still the golden one.
  expect_bit_exact(in, Method::kLk, hw, "ordering trace");
}

// ------------------------------------------------------------ timing like hardware

namespace {
HwConfig unlimited_memory() {
  HwConfig hw;
  for (const char* a :
       {"dram.channels=64", "dram.bytes_per_clock=4096", "dram.latency_cycles=0", "dram.row_miss_cycles=0",
        "cache.size_bytes=1048576", "source.fragments_per_clock=4", "distributor.fragments_per_clock=4",
        "distributor.tile_pixels=8", "distributor.fifo_depth=256", "ordering.window=16"})
    apply_hw_override(hw, a);
  return hw;
}
}  // namespace

// Small tiles and deep ROP input FIFOs spread a triangle's fragments over the
// ROPs; with 16-pixel tiles and 16-entry FIFOs the distributor's head-of-line
// blocking caps cloth at about 2.2 fragments per clock (a finding, not a bug).
TEST(Timing, FragmentsPerClockGrowWithRopsUntilTheSourceLimits) {
  std::vector<double> fpc;
  for (uint32_t n : {1u, 2u, 4u, 8u, 16u}) {
    HwConfig hw = unlimited_memory();
    apply_hw_override(hw, "distributor.rop_units=" + std::to_string(n));
    const CycleRun r = run_cycle(scene_input("cloth", 16), method_config(Method::kLk), hw);
    fpc.push_back(r.stats.fragments_per_clock);
  }
  EXPECT_GT(fpc[1], 1.5 * fpc[0]) << "2 ROPs should nearly double 1 ROP's rate: " << fpc[0] << " -> " << fpc[1];
  EXPECT_GT(fpc[2], 1.5 * fpc[1]) << "4 ROPs vs 2: " << fpc[1] << " -> " << fpc[2];
  for (double f : fpc) EXPECT_LE(f, 4.0) << "never faster than the source's 4 fragments per clock";
  EXPECT_GT(fpc[4], 0.9 * 4.0) << "16 ROPs should reach the source limit of 4 per clock";
  EXPECT_LT(fpc[4], 1.25 * fpc[3]) << "past the source limit more ROPs add little: " << fpc[3] << " -> " << fpc[4];
}

TEST(Timing, SmallDramBandwidthIsMemoryBoundAndTheReportSaysSo) {
  HwConfig hw;
  apply_hw_override(hw, "dram.channels=1");
  apply_hw_override(hw, "dram.bytes_per_clock=2");
  const CycleRun r = run_cycle(scene_input("cloth", 16), method_config(Method::kLk), hw);
  EXPECT_TRUE(r.stats.memory_bound) << "DRAM utilization " << r.stats.dram_utilization;
  EXPECT_EQ(r.stats.bottleneck.kind, Bottleneck::Kind::kBandwidth) << format_bottleneck(r.stats);
  EXPECT_EQ(format_bottleneck(r.stats).rfind("bandwidth (dram):", 0), 0u) << format_bottleneck(r.stats);
  const CycleRun fast = run_cycle(scene_input("cloth", 16), method_config(Method::kLk), unlimited_memory());
  EXPECT_FALSE(fast.stats.memory_bound) << format_bottleneck(fast.stats);
  EXPECT_NE(fast.stats.bottleneck.kind, Bottleneck::Kind::kBandwidth) << format_bottleneck(fast.stats);
  EXPECT_GT(r.stats.total_cycles, 3 * fast.stats.total_cycles);
}

// The pipeline's cost is linear in its input (without compression: the
// second drawing's tiles compress otherwise than the first's).
TEST(Timing, ASceneDrawnTwiceCostsTwiceTheCycles) {
  for (const char* cfg : {"default", "narrow", "wide"}) {
    const HwConfig hw = without_compression(load_hw_config(kSource + "/configs/" + cfg + ".toml"));
    const CycleRun once = run_cycle(scene_input("cloth", 16, 1), method_config(Method::kLk), hw);
    const CycleRun twice = run_cycle(scene_input("cloth", 16, 2), method_config(Method::kLk), hw);
    const double ratio = double(twice.stats.total_cycles) / double(once.stats.total_cycles);
    EXPECT_NEAR(ratio, 2.0, 0.10) << cfg << ": twice the fragments, " << ratio << "x the cycles (bound: 5%)";
  }
}

TEST(Timing, ActivitiesAddUpToTheRunAndIdleUnitsCostNoActivations) {
  const CycleRun r = run_cycle(scene_input("eight-layers", 4), method_config(Method::kLk), HwConfig{});
  for (const auto& u : r.stats.units) {
    uint64_t sum = 0;
    for (uint64_t c : u.stats.cycles) sum += c;
    EXPECT_EQ(sum, r.stats.total_cycles) << u.name << ": activity cycles must cover the run exactly";
  }
  // Event-driven: far fewer unit runs than unit-cycles of a clocked model, and
  // one SystemC activation per cycle in which any unit runs, at most.
  EXPECT_LT(double(r.stats.unit_runs), 0.2 * double(r.stats.total_cycles) * double(r.stats.units.size()));
  EXPECT_LE(r.stats.activations, r.stats.total_cycles + 1);
  EXPECT_LT(r.stats.activations, r.stats.unit_runs);
}

TEST(Timing, MethodsInstantiateOnlyTheUnitsTheyUse) {
  auto kinds = [](Method m) {
    std::set<std::string> k;
    const CycleRun r = run_cycle(scene_input("testcard", 1), method_config(m), HwConfig{});
    for (const auto& u : r.stats.units) k.insert(u.kind);
    return k;
  };
  EXPECT_EQ(kinds(Method::kLk).count("sample_sorter"), 1u);
  EXPECT_EQ(kinds(Method::kLk).count("coverage_tracker"), 1u);
  EXPECT_EQ(kinds(Method::kEnderton).count("sample_sorter"), 0u);
  EXPECT_EQ(kinds(Method::kEnderton).count("alpha_ref_gen"), 1u);
  EXPECT_EQ(kinds(Method::kOpaque).count("alpha_ref_gen"), 0u);
  EXPECT_EQ(kinds(Method::kA2c).count("coverage_tracker"), 0u);
  // hashed and hashed-a2c are stateless: their thresholds are hashed in the
  // coverage selection before the depth test, so no tracker, sorter or
  // alpha-reference generator.
  // slab reads and writes its layers at the depth test and the writeback.
  for (Method m : {Method::kHashed, Method::kHashedA2c, Method::kSlab}) {
    const std::set<std::string> want = {"trace_source", "distributor", "pixel_ordering", "depth_test", "writeback"};
    EXPECT_EQ(kinds(m), want) << to_string(m);
  }
  // wboit: one blend pass, no stochastic units.
  EXPECT_EQ(kinds(Method::kWboit).count("blend"), 1u);
  EXPECT_EQ(kinds(Method::kWboit).count("writeback"), 0u);
  EXPECT_EQ(kinds(Method::kWboit).count("alpha_ref_gen"), 0u);
  // lk+depth+ac: a blend pipeline for total alpha and accumulation, lk's for the stochastic pass.
  EXPECT_EQ(kinds(Method::kLkDepthAc).count("blend"), 1u);
  EXPECT_EQ(kinds(Method::kLkDepthAc).count("coverage_tracker"), 1u);
}

// The cost of every pass: a multi-pass method reports each pass's cycles and
// DRAM bytes per buffer, and the totals are their sums; the total-alpha pass
// moves transmittance bytes only, the accumulation pass reads the stochastic
// depth and moves accum bytes, the depth-only stochastic pass writes no
// colour. A single-pass method reports no passes and no render targets.
TEST(Timing, EveryPassIsChargedAndReportedPerBuffer) {
  HwConfig hw;
  apply_hw_override(hw, "cache.size_bytes=4096");  // small: the passes' lines reach DRAM
  apply_hw_override(hw, "cache.ways=4");
  const InputSpec in = scene_input("cloth", 16);
  const CycleRun r = run_cycle(in, method_config(Method::kLkDepthAc), hw);
  ASSERT_EQ(r.stats.passes.size(), 3u);
  const auto idx = [](Buffer b) { return size_t(b); };
  const PassStats &ta = r.stats.passes[0], &st = r.stats.passes[1], &ac = r.stats.passes[2];
  EXPECT_EQ(ta.name, "total_alpha");
  EXPECT_EQ(st.name, "stochastic");
  EXPECT_EQ(ac.name, "accumulate");
  EXPECT_GT(ta.dram.bytes_written[idx(Buffer::kTransmittance)], 0u);
  EXPECT_EQ(ta.dram.bytes_written[idx(Buffer::kDepth)], 0u) << "the total-alpha pass wrote depth";
  EXPECT_EQ(ta.dram.bytes_written[idx(Buffer::kAccum)], 0u);
  EXPECT_GT(st.dram.bytes_written[idx(Buffer::kDepth)], 0u);
  EXPECT_EQ(st.dram.bytes_written[idx(Buffer::kColor)], 0u) << "a depth-based stochastic pass stores depth only";
  EXPECT_GT(ac.dram.bytes_written[idx(Buffer::kAccum)], 0u);
  EXPECT_GT(ac.dram.bytes_read[idx(Buffer::kDepth)], 0u) << "the accumulation pass tests the stochastic depth";
  EXPECT_EQ(ac.dram.bytes_written[idx(Buffer::kDepth)], 0u) << "the accumulation pass's depth test wrote";
  uint64_t cycles = 0;
  DramStats sum;
  for (const auto& p : r.stats.passes) {
    EXPECT_GT(p.total_cycles, 0u) << p.name;
    cycles += p.total_cycles;
    for (size_t b = 0; b < size_t(kBuffers); ++b) {
      sum.bytes_read[b] += p.dram.bytes_read[b];
      sum.bytes_written[b] += p.dram.bytes_written[b];
    }
  }
  EXPECT_EQ(r.stats.total_cycles, cycles);
  EXPECT_EQ(r.stats.dram.bytes_read, sum.bytes_read);
  EXPECT_EQ(r.stats.dram.bytes_written, sum.bytes_written);
  // The report: per pass and per buffer; a single-pass method has neither.
  ReportContext ctx;
  ctx.input = in;
  ctx.config = method_config(Method::kLkDepthAc);
  const auto j = cycle_report(ctx, r, std::nullopt);
  ASSERT_TRUE(j["timing"].contains("passes"));
  EXPECT_EQ(j["timing"]["passes"][0]["dram"]["transmittance"]["bytes_written"].get<uint64_t>(),
            ta.dram.bytes_written[idx(Buffer::kTransmittance)]);
  EXPECT_EQ(j["timing"]["passes"][2]["dram"]["accum"]["bytes_written"].get<uint64_t>(),
            ac.dram.bytes_written[idx(Buffer::kAccum)]);
  const CycleRun lk = run_cycle(in, method_config(Method::kLk), hw);
  EXPECT_TRUE(lk.stats.passes.empty());
  ctx.config = method_config(Method::kLk);
  const auto jl = cycle_report(ctx, lk, std::nullopt);
  EXPECT_FALSE(jl["timing"].contains("passes")) << "a single-pass method reports no passes";
  EXPECT_FALSE(jl["timing"]["dram"].contains("transmittance")) << "lk has no render targets";
  EXPECT_FALSE(jl["timing"]["dram"].contains("accum"));
  // A multi-pass method costs about its pass count in cycles, not more.
  const double ratio = double(r.stats.total_cycles) / double(lk.stats.total_cycles);
  EXPECT_GT(ratio, 1.5) << "three passes cost " << ratio << "x lk";
  EXPECT_LT(ratio, 4.5) << "three passes cost " << ratio << "x lk";
}

// ------------------------------------------------------------ sorter algorithms

TEST(SortVariants, EveryNetworkGivesTheReferenceOrder) {
  std::mt19937_64 rng(3);
  for (SorterKind k : {SorterKind::kBitonic, SorterKind::kRank, SorterKind::kSerial})
    for (int n : {1, 2, 4, 8, 16, 32, 64}) {
      auto algo = make_sorter(k, n);
      for (int trial = 0; trial < 200; ++trial) {
        const int m = int(rng() % uint64_t(n + 1));
        float stored[64];
        uint64_t keys[64], ref[64];
        const int distinct = 1 + int(rng() % 4);  // few distinct depths, as in a pixel: many ties
        for (int i = 0; i < m; ++i) {
          stored[i] = float(rng() % uint64_t(distinct)) / 4.0f;
          keys[i] = ref[i] = sort_key(stored[i], uint32_t(i));
        }
        std::shuffle(keys, keys + m, rng);
        algo->sort(keys, m);
        sort_keys(ref, m);
        for (int i = 0; i < m; ++i) ASSERT_EQ(keys[i], ref[i]) << algo->name() << " N=" << n << " m=" << m;
        // And the grouped sort the SystemC sorter runs gives the same permutation.
        uint8_t order[64];
        uint64_t mask = m == 64 ? ~0ull : (1ull << m) - 1;
        ASSERT_EQ(sort_by_stored_depth(stored, mask, order), m);
        for (int i = 0; i < m; ++i) ASSERT_EQ(order[i], sort_key_sample(ref[i]));
      }
    }
}

TEST(SortVariants, ComparatorCounts) {
  EXPECT_EQ(make_sorter(SorterKind::kBitonic, 16)->comparators(), 10u * 8u);
  EXPECT_EQ(make_sorter(SorterKind::kRank, 16)->comparators(), 16u * 15u / 2u);
  EXPECT_EQ(make_sorter(SorterKind::kSerial, 16)->comparators(), 16u);
}
