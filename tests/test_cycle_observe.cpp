// What observes a run without changing it: the per-interval statistics
// (--stats-interval), waveforms (--vcd) and the attribution of costs to
// draws and screen tiles (--per-draw, --maps).
#include "tests/cycle_test_util.h"

using namespace ropsim;
using namespace cycle_test;

// ------------------------------------------------------------ --stats-interval

namespace {

CycleRun run_with_intervals(const InputSpec& in, Method m, const HwConfig& hw, uint64_t interval, bool lockstep) {
  CycleOptions opt;
  opt.stats_interval = interval;
  opt.lockstep = lockstep;
  return run_cycle(in, method_config(m), hw, opt);
}

}  // namespace

// Every column of the per-interval statistics adds up to the run's total, and
// the rows are the run's cycles cut every N: for single- and multi-pass
// methods, on every design.
TEST(StatsInterval, RowsAddUpToTheRunsTotals) {
  for (const auto& config : timing_config_files()) {
    const HwConfig hw = load_hw_config(config);
    for (Method m : {Method::kLk, Method::kOpaque, Method::kLkDepthAc}) {
      const std::string what = std::string("cloth 16 spp ") + to_string(m) + " on " + config;
      const uint64_t n = 997;  // prime: intervals cut busy spans and passes anywhere
      const CycleRun r = run_with_intervals(scene_input("cloth", 16), m, hw, n, false);
      ASSERT_TRUE(r.intervals) << what;
      const IntervalLog& log = *r.intervals;
      EXPECT_EQ(log.rows(), (r.stats.total_cycles + n - 1) / n) << what << ": one row per interval of the run";
      IntervalRow sum;
      for (size_t i = 0; i < log.rows(); ++i) {
        const IntervalRow& x = log.at(i);
        sum.fragments_retired += x.fragments_retired;
        sum.samples_written += x.samples_written;
        sum.samples_blended += x.samples_blended;
        for (size_t b = 0; b < size_t(kBuffers); ++b) {
          sum.dram_bytes_read[b] += x.dram_bytes_read[b];
          sum.dram_bytes_written[b] += x.dram_bytes_written[b];
        }
        sum.cache_hits += x.cache_hits;
        sum.cache_misses += x.cache_misses;
      }
      EXPECT_EQ(sum.fragments_retired, r.counters.fragments)
          << what << ": every fragment retires once per pass (the counters count each pass's)";
      EXPECT_EQ(sum.samples_written, r.counters.samples_written) << what;
      EXPECT_EQ(sum.samples_blended, r.counters.samples_blended) << what;
      for (size_t b = 0; b < size_t(kBuffers); ++b) {
        EXPECT_EQ(sum.dram_bytes_read[b], r.stats.dram.bytes_read[b]) << what << " buffer " << b;
        EXPECT_EQ(sum.dram_bytes_written[b], r.stats.dram.bytes_written[b]) << what << " buffer " << b;
      }
      CacheStats cache;
      for (const auto& c : r.stats.caches) cache += c;
      uint64_t hits = 0, misses = 0;
      for (size_t b = 0; b < size_t(kBuffers); ++b) {
        hits += cache.read_hits[b] + cache.write_hits[b];
        misses += cache.read_misses[b] + cache.write_misses[b];
      }
      EXPECT_EQ(sum.cache_hits, hits) << what;
      EXPECT_EQ(sum.cache_misses, misses) << what;
      ASSERT_GT(hits + misses, 0u) << what << ": the test needs cache traffic";
      // Each unit kind's activity, per activity, over the rows and over the units.
      for (size_t k = 0; k < log.kinds().size(); ++k) {
        std::array<uint64_t, kActivities> rows{}, units{};
        for (size_t i = 0; i < log.rows(); ++i)
          for (int a = 0; a < kActivities; ++a) rows[size_t(a)] += log.activity(int(k), i)[size_t(a)];
        uint64_t instances_cycles = 0;
        for (const auto& u : r.stats.units)
          if (u.kind == log.kinds()[k])
            for (int a = 0; a < kActivities; ++a) {
              units[size_t(a)] += u.stats.cycles[size_t(a)];
              instances_cycles += u.stats.cycles[size_t(a)];
            }
        EXPECT_EQ(rows, units) << what << ": " << log.kinds()[k];
        EXPECT_GT(instances_cycles, 0u) << what << ": " << log.kinds()[k];
      }
      // No row holds more unit cycles than its interval has, per instance.
      for (size_t k = 0; k < log.kinds().size(); ++k) {
        uint64_t instances = 0;
        for (const auto& u : r.stats.units) instances += u.kind == log.kinds()[k];
        for (size_t i = 0; i < log.rows(); ++i) {
          uint64_t c = 0;
          for (uint64_t x : log.activity(int(k), i)) c += x;
          EXPECT_LE(c, instances * n) << what << ": " << log.kinds()[k] << " row " << i;
        }
      }
      // The CSV: a header and one line per row, every line with every column.
      const std::string csv = interval_csv(r);
      const size_t cols = interval_columns(r).size();
      std::istringstream lines(csv);
      size_t count = 0;
      for (std::string line; std::getline(lines, line); ++count)
        EXPECT_EQ(size_t(std::count(line.begin(), line.end(), ',')) + 1, cols) << what << " line " << count;
      EXPECT_EQ(count, log.rows() + 1) << what;
    }
  }
}

// The rows are recorded by the cycle events happen at, so a decoupled run
// gives the lockstep run's rows exactly, and recording them changes nothing.
TEST(StatsInterval, DecoupledRowsEqualLockstepRowsAndTheRunIsUnchanged) {
  const HwConfig hw;
  const InputSpec in = scene_input("cloth", 16);
  const CycleRun dec = run_with_intervals(in, Method::kLk, hw, 500, false);
  const CycleRun lock = run_with_intervals(in, Method::kLk, hw, 500, true);
  EXPECT_EQ(interval_csv(dec), interval_csv(lock));
  const CycleRun plain = run_cycle(in, method_config(Method::kLk), hw);
  expect_same_timing(dec.stats, plain.stats, "cloth lk with and without --stats-interval");
  EXPECT_EQ(dec.stats.total_cycles, plain.stats.total_cycles);
}

// ------------------------------------------------------------ waveforms (waveform.h, --vcd)

// The recorder alone: a value set before the window is the one it starts
// with, the last set at a cycle wins, nothing after the window is kept, a
// FIFO's occupancy comes from pushes and pops recorded out of cycle order
// (a decoupled producer ahead of its consumer), and a signal's events going
// back in time are a broken invariant.
TEST(Waveform, RecordsEachSignalAtItsOwnCycle) {
  Waveform w(10, 20);
  const int st = w.add_state("rop0", "unit", {"idle", "busy", "memory"});
  const int occ = w.add_occupancy("rop0", "fifo_in");
  w.set(st, 3, 2);   // before the window: overridden by the next
  w.set(st, 8, 1);   // the value at cycle 10
  w.set(st, 12, 2);  // two sets at cycle 12: the last wins
  w.set(st, 12, 0);
  w.set(st, 15, 1);
  w.set(st, 21, 2);                                       // after the window: dropped
  for (uint64_t t : {5, 10, 14, 14, 16}) w.push(occ, t);  // the producer runs ahead...
  for (uint64_t t : {9, 13, 16, 25}) w.pop(occ, t);       // ...of the consumer
  std::string text;
  w.write_vcd("top", "test", 100, [&](std::string_view s) { text += s; });
  const ropsim_test::Vcd v = ropsim_test::parse_vcd(text);
  // Ten 100 ps time units per cycle: the clock rises at 10c and falls at 10c + 5.
  EXPECT_EQ(v.timescale, "100 ps");
  EXPECT_EQ(v.stamps.front(), 100u);
  EXPECT_EQ(v.stamps.back(), 205u);
  EXPECT_EQ(v.stamps.size(), 22u);
  const int clk = v.find("top", "clk");
  ASSERT_GE(clk, 0) << "no clock";
  EXPECT_EQ(v.vars[size_t(clk)].type, "wire");
  EXPECT_EQ(v.vars[size_t(clk)].width, 1);
  const std::vector<std::string> clock = v.trace(size_t(clk), 100, 209);
  for (size_t i = 0; i < clock.size(); ++i) EXPECT_EQ(clock[i], i % 10 < 5 ? "1" : "0") << "clk at time " << 100 + i;
  for (const auto& c : v.changes) {
    if (int(c.var) == clk) continue;
    EXPECT_EQ(c.time % 10, 0u) << "a signal changes off the rising edge, at time " << c.time;
  }
  const std::vector<std::string> unit = v.trace_cycles(size_t(v.find("top.rop0", "unit")), 10, 20);
  EXPECT_EQ(unit, (std::vector<std::string>{"busy", "busy", "idle", "idle", "idle", "busy", "busy", "busy", "busy",
                                            "busy", "busy"}));
  const std::vector<std::string> fifo = v.trace_cycles(size_t(v.find("top.rop0", "fifo_in")), 10, 20);
  // Entries in at a cycle: pushed at or before it, popped after it.
  const uint64_t expect[] = {1, 1, 1, 0, 2, 2, 2, 2, 2, 2, 2};
  for (size_t i = 0; i < fifo.size(); ++i)
    EXPECT_EQ(ropsim_test::Vcd::number(fifo[i]), expect[i]) << "occupancy at cycle " << 10 + i;
  // A run that ends inside the window: nothing after its last cycle.
  std::string short_run;
  w.write_vcd("top", "test", 16, [&](std::string_view s) { short_run += s; });
  EXPECT_EQ(ropsim_test::parse_vcd(short_run).stamps.back(), 155u) << "the falling edge of cycle 15";
  EXPECT_THROW(w.set(st, 14, 1), InternalError) << "an event before the signal's last one";
}

namespace {

std::string wave_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("ropsim-wave-" + std::to_string(::getpid()) + "-" + name)).string();
}

std::string slurp_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

CycleRun run_with_vcd(const InputSpec& in, const HwConfig& hw, const std::string& path, uint64_t first, uint64_t last,
                      bool lockstep) {
  CycleOptions opt;
  opt.vcd_path = path;
  opt.vcd_first = first;
  opt.vcd_last = last;
  opt.lockstep = lockstep;
  return run_cycle(in, method_config(Method::kLk), hw, opt);
}

}  // namespace

// The waveform records every event at its own cycle, so a decoupled run
// (units ahead of SystemC time) writes the lockstep run's file byte for byte,
// and either run's timing is the run's without --vcd.
TEST(Waveform, DecoupledAndLockstepRunsWriteTheSameFile) {
  const HwConfig hw;
  const InputSpec in = scene_input("cloth", 16);
  const std::string a = wave_path("dec.vcd"), b = wave_path("lock.vcd");
  const CycleRun dec = run_with_vcd(in, hw, a, 30000, 40000, false);
  const CycleRun lock = run_with_vcd(in, hw, b, 30000, 40000, true);
  const CycleRun plain = run_cycle(in, method_config(Method::kLk), hw);
  ASSERT_TRUE(dec.stats.decoupled);
  ASSERT_FALSE(lock.stats.decoupled);
  const std::string da = slurp_file(a), lb = slurp_file(b);
  std::filesystem::remove(a);
  std::filesystem::remove(b);
  ASSERT_GT(da.size(), 10000u) << "the waveform is nearly empty";
  EXPECT_EQ(ropsim_test::first_byte_difference(da, lb), "")
      << "the decoupled run's waveform differs from the lockstep run's";
  expect_same_timing(dec.stats, plain.stats, "cloth lk with and without --vcd");
  EXPECT_EQ(dec.stats.unit_runs, plain.stats.unit_runs) << "--vcd changed how the units ran";
}

// A waveform of the whole run adds up to the report: each unit's cycles in
// each named activity are its activity cycles, each FIFO's occupancy summed
// over the cycles is its mean times the run's cycles and peaks at its
// maximum, the DRAM channels' busy cycles and final row-miss counts are the
// DRAM's. So the waveform shows what the statistics count, cycle by cycle.
// A multi-pass method's passes follow each other, each in its own scope.
TEST(Waveform, AWholeRunAddsUpToTheReport) {
  HwConfig hw;
  apply_hw_override(hw, "distributor.rop_units=2");
  for (Method m : {Method::kLk, Method::kLkDepthAc}) {
    const std::string what = to_string(m), path = wave_path("all.vcd");
    CycleOptions opt;
    opt.vcd_path = path;
    const CycleRun run = run_cycle(scene_input("cloth", 4), method_config(m), hw, opt);
    const ropsim_test::Vcd v = ropsim_test::parse_vcd(slurp_file(path));
    std::filesystem::remove(path);
    const CycleStats& s = run.stats;
    ASSERT_EQ(v.stamps.size(), 2 * s.total_cycles) << what << ": two time stamps per cycle of the run";
    // Each pass: its scope prefix and its cycles [from, to) in the run.
    struct Pass {
      std::string prefix;
      uint64_t from, to;
    };
    std::vector<Pass> passes;
    if (s.passes.empty()) passes.push_back(Pass{"top.", 0, s.total_cycles});
    for (const auto& p : s.passes) {
      const uint64_t from = passes.empty() ? 0 : passes.back().to;
      passes.push_back(Pass{"top." + p.name + ".", from, from + p.total_cycles});
    }
    ASSERT_EQ(passes.back().to, s.total_cycles) << what;
    auto pass_of = [&](const std::string& name) {  // "stochastic.rop0_depth_test", "stochastic.rop0.input"
      if (s.passes.empty()) return passes[0];
      for (const auto& p : passes)
        if (name.rfind(p.prefix.substr(4), 0) == 0) return p;
      ADD_FAILURE() << name << " belongs to no pass";
      return passes[0];
    };
    // Per variable: its changes; the cycles at each value, the sum and the
    // maximum of its numbers over [from, to).
    std::vector<std::vector<std::pair<uint64_t, std::string>>> changes(v.vars.size());
    for (const auto& c : v.changes) changes[c.var].emplace_back(c.time / 10, c.value);  // cycle c at time 10c
    struct Sums {
      std::map<std::string, uint64_t> cycles;
      uint64_t sum = 0, max = 0;
      std::string last;
    };
    auto sums = [&](int var, uint64_t from, uint64_t to) {
      Sums r;
      const auto& ch = changes[size_t(var)];
      for (size_t k = 0; k < ch.size(); ++k) {
        const uint64_t a = std::max(ch[k].first, from), b = std::min(k + 1 < ch.size() ? ch[k + 1].first : to, to);
        if (a >= b) continue;
        r.cycles[ch[k].second] += b - a;
        r.last = ch[k].second;
        if (v.vars[size_t(var)].type == "integer") {
          const uint64_t n = ropsim_test::Vcd::number(ch[k].second);
          r.sum += n * (b - a);
          r.max = std::max(r.max, n);
        }
      }
      return r;
    };
    for (const auto& u : s.units) {
      const Pass p = pass_of(u.name);
      const std::string scope = p.prefix + (u.rop >= 0 ? "rop" + std::to_string(u.rop) : u.kind);
      const int var = v.find(scope.substr(0, scope.size()), u.kind);
      ASSERT_GE(var, 0) << what << ": " << u.name << " is not " << scope << "." << u.kind;
      Sums got = sums(var, p.from, p.to);
      for (int a = 0; a < kActivities; ++a)
        EXPECT_EQ(got.cycles[to_string(Activity(a))], u.stats.cycles[size_t(a)])
            << what << ": " << u.name << ": cycles " << to_string(Activity(a));
    }
    for (const auto& f : s.fifos) {
      const Pass p = pass_of(f.name);
      const std::string local = s.passes.empty() ? f.name : f.name.substr(f.name.find('.') + 1);
      const auto dot = local.find('.');
      const std::string scope = p.prefix + (dot == std::string::npos ? "distributor" : local.substr(0, dot));
      const int var = v.find(scope, "fifo_" + (dot == std::string::npos ? local : local.substr(dot + 1)));
      ASSERT_GE(var, 0) << what << ": " << f.name;
      const Sums got = sums(var, p.from, p.to);
      EXPECT_NEAR(double(got.sum) / double(p.to - p.from), f.mean_occupancy, 1e-9) << what << ": " << f.name;
      EXPECT_EQ(got.max, f.max_occupancy) << what << ": " << f.name << " maximum occupancy";
    }
    uint64_t busy = 0, misses = 0;
    for (const auto& p : passes)
      for (uint32_t ch = 0; ch < hw.dram.channels; ++ch) {
        const int bus = v.find(p.prefix + "dram", "ch" + std::to_string(ch) + "_bus");
        const int rm = v.find(p.prefix + "dram", "ch" + std::to_string(ch) + "_row_misses");
        ASSERT_TRUE(bus >= 0 && rm >= 0) << what << ": " << p.prefix << " channel " << ch;
        Sums b = sums(bus, 0, s.total_cycles);
        busy += b.cycles["read"] + b.cycles["write"];
        misses += ropsim_test::Vcd::number(sums(rm, 0, s.total_cycles).last);
      }
    ASSERT_GT(s.dram.busy_cycles, 0u) << what << ": the test needs DRAM traffic";
    EXPECT_EQ(busy, s.dram.busy_cycles) << what << ": DRAM data-bus cycles";
    EXPECT_EQ(misses, s.dram.row_misses) << what << ": DRAM row misses";
  }
}

// ------------------------------------------------------------ attribution (attribution.h: --per-draw, --maps)

namespace {

uint64_t sum_of(const std::vector<uint64_t>& v) {
  uint64_t s = 0;
  for (uint64_t x : v) s += x;
  return s;
}

}  // namespace

// Every cost the cycle model charges to a draw or a screen tile adds up to
// the report's figure: per buffer, the draws' DRAM bytes read and written
// are the run's (compressed surfaces with their metadata traffic too, and
// the passes of a multi-pass method); per tile, the retirement cycles are
// pipeline_cycles, the units' cycles in each activity their counters (plus
// the cycles of units that never took a fragment), the cache misses the
// caches'. It observes only: every timing figure is the run's without it.
TEST(Attribution, DrawsAndTilesAddUpToTheReportAndChangeNothing) {
  HwConfig plain_hw, comp_hw;
  for (const char* o : {"compression.depth=true", "compression.color=true", "hiz.enable=true"})
    apply_hw_override(comp_hw, o);
  struct Case {
    Method m;
    HwConfig hw;
    const char* what;
  };
  for (const Case& c : {Case{Method::kLk, plain_hw, "lk"}, Case{Method::kLk, comp_hw, "lk, compressed, Hi-Z"},
                        Case{Method::kLkDepthAc, plain_hw, "lk+depth+ac (three passes)"}}) {
    const InputSpec in = scene_input("testcard", 4);
    CycleOptions opt;
    opt.breakdown = BreakdownRequest{true, true};
    const CycleRun run = run_cycle(in, method_config(c.m), c.hw, opt);
    const CycleRun plain = run_cycle(in, method_config(c.m), c.hw);
    const CycleStats& s = run.stats;
    expect_same_timing(s, plain.stats, c.what);
    EXPECT_EQ(s.dram.bytes_read, plain.stats.dram.bytes_read) << c.what;
    EXPECT_EQ(s.dram.bytes_written, plain.stats.dram.bytes_written) << c.what;
    ASSERT_TRUE(run.breakdown && run.tiles) << c.what;
    ASSERT_GT(run.breakdown->draws().size(), 1u) << c.what << ": the test needs several draws";
    const RunBreakdown::Draw total = run.breakdown->total();
    for (int b = 0; b < kBuffers; ++b) {
      EXPECT_EQ(total.dram_read[size_t(b)], s.dram.bytes_read[size_t(b)]) << c.what << ": " << to_string(Buffer(b));
      EXPECT_EQ(total.dram_written[size_t(b)], s.dram.bytes_written[size_t(b)])
          << c.what << ": " << to_string(Buffer(b));
    }
    EXPECT_GT(s.dram.total_bytes_written(), 0u) << c.what << ": the test needs write-backs";
    if (c.hw.compression.depth) {
      EXPECT_GT(s.compression.metadata_bytes_written[0], 0u) << c.what << ": the test needs metadata write-backs";
    }
    const Attribution& a = *run.tiles;
    EXPECT_EQ(a.tiles(), run.tiles_x * run.tiles_y);
    EXPECT_EQ(sum_of(a.retire_cycles()), s.pipeline_cycles) << c.what;
    for (int k = 0; k < kActivities; ++k) {
      uint64_t units = 0;
      for (const auto& u : s.units) units += u.stats.cycles[size_t(k)];
      EXPECT_EQ(sum_of(a.unit_cycles(k)) + a.unowned(k), units) << c.what << ": " << to_string(Activity(k));
    }
    CacheStats caches;
    for (const auto& cs : s.caches) caches += cs;
    EXPECT_EQ(sum_of(a.cache_misses()), caches.misses()) << c.what;
    uint64_t stalls = 0;
    for (Activity k : {Activity::kMemory, Activity::kHazard, Activity::kBlocked})
      stalls += sum_of(a.unit_cycles(int(k)));
    EXPECT_GT(stalls, 0u) << c.what << ": the test needs stalls";
  }
}

// The charges are made at the cycles of the events, so a decoupled run
// charges exactly what the lockstep run does (one ROP, where the two agree
// in every timing figure).
TEST(Attribution, DecoupledAndLockstepChargeTheSame) {
  const HwConfig hw = load_hw_config(ROPSIM_SOURCE_DIR "/configs/narrow.toml");
  CycleOptions opt;
  opt.breakdown = BreakdownRequest{true, true};
  const CycleRun dec = run_cycle(scene_input("testcard", 4), method_config(Method::kLk), hw, opt);
  opt.lockstep = true;
  const CycleRun lock = run_cycle(scene_input("testcard", 4), method_config(Method::kLk), hw, opt);
  ASSERT_TRUE(dec.stats.decoupled && !lock.stats.decoupled);
  for (size_t i = 0; i < tile_map_descs().size(); ++i)
    EXPECT_EQ(tile_map(*dec.tiles, i), tile_map(*lock.tiles, i)) << tile_map_descs()[i].name;
  for (int k = 0; k < kActivities; ++k) EXPECT_EQ(dec.tiles->unowned(k), lock.tiles->unowned(k));
  ASSERT_EQ(dec.breakdown->draws().size(), lock.breakdown->draws().size());
  for (const auto& [id, d] : dec.breakdown->draws()) {
    const auto& l = lock.breakdown->draws().at(id);
    EXPECT_EQ(d.dram_read, l.dram_read) << "draw " << id;
    EXPECT_EQ(d.dram_written, l.dram_written) << "draw " << id;
    EXPECT_EQ(d.cycles, l.cycles) << "draw " << id;
  }
}
