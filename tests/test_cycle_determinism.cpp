// Temporal decoupling changes nothing: decoupled and lockstep runs give the
// same image and every timing figure, with ideal and real memory and with
// compression, and the FIFO statistics do not depend on host order.
#include "tests/cycle_test_util.h"

using namespace ropsim;
using namespace cycle_test;

// ------------------------------------------------------------ temporal decoupling

namespace {

CycleRun run_mode(const InputSpec& in, Method m, const HwConfig& hw, bool lockstep) {
  CycleOptions opt;
  opt.lockstep = lockstep;
  return run_cycle(in, method_config(m), hw, opt);
}

}  // namespace

// Decoupled runs equal lockstep runs in every timing figure, not just the
// image: first with a cache that never misses to DRAM, over every config,
// scene and method.
TEST(Decoupling, EqualsLockstepExactlyWhenMemoryOrderCannotMatter) {
  for (const auto& config : timing_config_files()) {
    HwConfig hw = load_hw_config(config);
    apply_hw_override(hw, "cache.size_bytes=16777216");
    apply_hw_override(hw, "cache.fast_clear=true");
    for (const auto& [scene, spp] : std::vector<std::pair<std::string, int>>{{"cloth", 4}, {"eight-layers", 16}})
      for (Method m : {Method::kOpaque, Method::kEnderton, Method::kLk}) {
        const std::string what = scene + " " + std::to_string(spp) + " spp " + to_string(m) + " on " + config;
        const CycleRun lock = run_mode(scene_input(scene, spp), m, hw, true);
        const CycleRun dec = run_mode(scene_input(scene, spp), m, hw, false);
        ASSERT_FALSE(lock.stats.decoupled) << what;
        ASSERT_TRUE(dec.stats.decoupled) << what;
        expect_same_timing(dec.stats, lock.stats, what);
        EXPECT_EQ(ropsim_test::first_image_difference(dec.image, lock.image), "") << what;
        EXPECT_LT(double(dec.stats.unit_runs), (m == Method::kLk ? 0.6 : 0.9) * double(lock.stats.unit_runs))
            << what << ": decoupling must save unit activations";
      }
  }
}

// With real memory (misses, evictions, DRAM rows and channels shared by the
// ROPs) decoupled and lockstep runs are identical too: the scheduler runs the
// units of one cycle in a fixed order, and posted writes reach the caches in a
// fixed order, so no result depends on the order SystemC would pick.
TEST(Decoupling, EqualsLockstepExactlyWithRealMemory) {
  for (const auto& config : timing_config_files()) {
    const HwConfig hw = load_hw_config(config);
    for (Method m : {Method::kOpaque, Method::kEnderton, Method::kLk, Method::kWboit, Method::kLkDepthAc}) {
      const std::string what = std::string("cloth 16 spp ") + to_string(m) + " on " + config;
      const CycleRun lock = run_mode(scene_input("cloth", 16), m, hw, true);
      const CycleRun dec = run_mode(scene_input("cloth", 16), m, hw, false);
      ASSERT_GT(dec.stats.dram.reads, 0u) << what << ": the test needs DRAM traffic";
      expect_same_timing(dec.stats, lock.stats, what);
      EXPECT_EQ(first_state_difference(*dec.state, *lock.state), "") << what;
    }
  }
  // The largest design: 64 ROPs (386 units on one scheduler).
  HwConfig hw;
  apply_hw_override(hw, "distributor.rop_units=64");
  apply_hw_override(hw, "distributor.tile_pixels=8");
  const CycleRun lock = run_mode(scene_input("cloth", 4), Method::kLk, hw, true);
  const CycleRun dec = run_mode(scene_input("cloth", 4), Method::kLk, hw, false);
  ASSERT_EQ(dec.stats.units.size(), 2u + 64u * 6u);
  expect_same_timing(dec.stats, lock.stats, "64 ROPs");
}

// With surface compression and Hi-Z too: a tile is compressed as the caches
// see it (the store less the writes posted but not yet applied), so a
// writeback unit running ahead of SystemC time changes no tile's size.
TEST(Decoupling, EqualsLockstepExactlyWithCompression) {
  const HwConfig hw = load_hw_config(kSource + "/configs/default.toml");
  ASSERT_TRUE(hw.compression.depth && hw.compression.color && hw.hiz.enable);
  for (const auto& [scene, spp] : std::vector<std::pair<std::string, int>>{{"cloth", 16}, {"smoke", 4}})
    for (Method m : {Method::kOpaque, Method::kLk, Method::kEnderton, Method::kWboit}) {
      const std::string what = scene + " " + std::to_string(spp) + " spp " + to_string(m) + " on default.toml";
      GoldenConfig g = method_config(m);
      g.compression = hw.compression.setup();
      CycleOptions lo, de;
      lo.lockstep = true;
      const CycleRun lock = run_cycle(scene_input(scene, spp), g, hw, lo);
      const CycleRun dec = run_cycle(scene_input(scene, spp), g, hw, de);
      ASSERT_TRUE(dec.stats.compression_on) << what;
      expect_same_timing(dec.stats, lock.stats, what);
      const CompressionTraffic &a = dec.stats.compression, &b = lock.stats.compression;
      for (int k = 0; k < kBuffers; ++k) {
        EXPECT_EQ(a.bytes_written[size_t(k)], b.bytes_written[size_t(k)]) << what << ", buffer " << k;
        EXPECT_EQ(a.bytes_read[size_t(k)], b.bytes_read[size_t(k)]) << what << ", buffer " << k;
        EXPECT_EQ(a.writes_per_class[size_t(k)], b.writes_per_class[size_t(k)]) << what << ", buffer " << k;
        EXPECT_EQ(a.writes_cleared[size_t(k)], b.writes_cleared[size_t(k)]) << what << ", buffer " << k;
      }
      EXPECT_EQ(a.hiz_rejected, b.hiz_rejected) << what;
      EXPECT_EQ(a.metadata_misses, b.metadata_misses) << what;
      uint64_t compressed = 0;
      for (int k = 0; k < kBuffers; ++k)
        compressed += a.writes_per_class[size_t(k)][1] + a.writes_per_class[size_t(k)][2];
      EXPECT_GT(compressed, 0u) << what << ": the test needs compressed tiles";
    }
}

// Occupancy statistics from push and pop cycles that reach the FIFO out of
// cycle order (one side decoupled) equal those of the same events in order.
TEST(Decoupling, OccupancyStatsDoNotDependOnHostOrder) {
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 50; ++trial) {
    const uint32_t cap = 1 + uint32_t(rng() % 6);
    // A legal schedule: entry i pushed at p[i], popped at q[i] > p[i]; both
    // non-decreasing; entry i + cap pushed after entry i is popped.
    std::vector<uint64_t> p, q;
    uint64_t tp = 0, tq = 0;
    for (int i = 0; i < 200; ++i) {
      tp += rng() % 3;
      if (i >= int(cap)) tp = std::max(tp, q[size_t(i) - cap] + 1);
      p.push_back(tp);
      tq = std::max(tq + rng() % 3, tp + 1);
      q.push_back(tq);
    }
    const uint64_t end = q.back() + 5;
    // In cycle order.
    OccupancyStats in_order(cap);
    std::vector<std::pair<uint64_t, int>> ev;
    for (size_t i = 0; i < p.size(); ++i) ev.push_back({p[i], 1}), ev.push_back({q[i], 0});
    std::stable_sort(ev.begin(), ev.end(), [](auto& a, auto& b) { return a.first < b.first; });
    for (auto& e : ev) e.second ? in_order.push(e.first) : in_order.pop(e.first);
    // Host order: the producer runs ahead by up to `cap` pushes.
    OccupancyStats ahead(cap);
    size_t i = 0, j = 0;
    while (j < q.size()) {
      if (i < p.size() && i < j + cap && (rng() % 2))
        ahead.push(p[i++]);
      else if (j < i)
        ahead.pop(q[j++]);
      else
        ahead.push(p[i++]);
    }
    double m1, m2;
    uint64_t f1, f2;
    uint32_t x1, x2;
    in_order.finish(end, m1, f1, x1);
    ahead.finish(end, m2, f2, x2);
    // Brute force over cycles.
    uint64_t area = 0, full = 0;
    uint32_t mx = 0;
    for (uint64_t t = 0; t < end; ++t) {
      uint32_t occ = 0;
      for (size_t k = 0; k < p.size(); ++k) occ += p[k] <= t && t < q[k];
      area += occ;
      full += occ == cap;
      mx = std::max(mx, occ);
    }
    EXPECT_DOUBLE_EQ(m1, double(area) / double(end)) << "trial " << trial;
    EXPECT_EQ(f1, full) << "trial " << trial;
    EXPECT_EQ(x1, mx) << "trial " << trial;
    EXPECT_DOUBLE_EQ(m2, m1) << "trial " << trial;
    EXPECT_EQ(f2, f1) << "trial " << trial;
    EXPECT_EQ(x2, x1) << "trial " << trial;
  }
}
