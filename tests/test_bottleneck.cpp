// The bottleneck: one rule (sim/fidelity/common/bottleneck.h) classifies the frame from
// the timing model's own bounds in every fidelity. The rule on hand-made
// bounds at its threshold, then designs built to be throughput-, bandwidth-
// and latency-bound, each in the cycle and the approximate fidelity.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "sim/fidelity/approximate/approximate.h"
#include "sim/fidelity/common/bottleneck.h"
#include "sim/fidelity/cycle/cycle_run.h"
#include "sim/fidelity/functional/driver.h"
#include "sim/report/cycle_report.h"

using namespace ropsim;

namespace {

const std::string kSource = ROPSIM_SOURCE_DIR;

InputSpec scene(const std::string& name, int spp) {
  InputSpec in;
  in.scene.name = name;
  in.scene.spp = spp;
  return in;
}

HwConfig with(HwConfig hw, const std::vector<std::string>& sets) {
  for (const auto& a : sets) apply_hw_override(hw, a);
  return hw;
}

/// hw without compression and Hi-Z (as configs/uncompressed.toml).
HwConfig without_compression(HwConfig hw) {
  return with(std::move(hw), {"compression.depth=false", "compression.color=false", "hiz.enable=false"});
}

/// Every resource a design's bounds name, for the failure messages.
std::string describe(const Bottleneck& b) { return format_bottleneck(b) + "; bounds: " + format_bounds(b); }

/// Fast memory everywhere, so that only what a test narrows can bound the frame.
HwConfig ample_memory() {
  return with(HwConfig{}, {"dram.channels=8", "dram.bytes_per_clock=256", "dram.latency_cycles=0",
                           "dram.row_miss_cycles=0", "cache.size_bytes=1048576"});
}

/// The designs built to be each kind, with the resource that must bound them.
struct Case {
  const char* what;
  HwConfig hw;
  Bottleneck::Kind kind;
  const char* resource;  // "" for latency
};

std::vector<Case> cases() {
  return {
      // One ROP with a serial sorter (one sample a clock) and ample memory:
      // the sorter works m clocks per fragment, every other unit about one.
      {"a serial sorter", with(ample_memory(), {"distributor.rop_units=1", "sorter.kind=serial"}),
       Bottleneck::Kind::kThroughput, "sample_sorter"},
      // One hash lane: the alpha-reference generator takes m clocks a fragment.
      {"one hash lane", with(ample_memory(), {"distributor.rop_units=1", "alpha_ref.lanes=1"}),
       Bottleneck::Kind::kThroughput, "alpha_ref_gen"},
      // A one-byte-a-clock DRAM: a 64-byte line takes 64 clocks of its bus.
      {"a one-byte DRAM", with(HwConfig{}, {"dram.channels=1", "dram.bytes_per_clock=1", "cache.size_bytes=4096"}),
       Bottleneck::Kind::kBandwidth, "dram"},
      // Ten thousand cycles a read with ample bandwidth and one fragment
      // waiting for memory at a time: every miss is a round trip.
      {"a far DRAM",
       with(HwConfig{}, {"dram.channels=8", "dram.bytes_per_clock=256", "dram.latency_cycles=10000",
                         "cache.size_bytes=4096", "depth_test.max_outstanding=1"}),
       Bottleneck::Kind::kLatency, ""},
  };
}

}  // namespace

// The rule at its threshold: a bound of 80 % of the frame bounds it, one just
// below leaves the frame latency-bound; the largest bound wins, equal ones in
// the order given, zero bounds are dropped; the class is the line's start.
TEST(Bottleneck, RuleAtItsThreshold) {
  using K = ResourceBound::Kind;
  Bottleneck b = classify_bottleneck({{"depth_test", K::kThroughput, 30}, {"dram", K::kBandwidth, 80}}, 100);
  EXPECT_EQ(b.kind, Bottleneck::Kind::kBandwidth) << describe(b);
  EXPECT_EQ(b.resource, "dram");
  EXPECT_EQ(b.bound_cycles, 80);
  EXPECT_EQ(format_bottleneck(b).rfind("bandwidth (dram): ", 0), 0u) << format_bottleneck(b);
  ASSERT_EQ(b.bounds.size(), 2u);
  EXPECT_EQ(b.bounds[0].name, "dram") << "largest first";

  b = classify_bottleneck({{"depth_test", K::kThroughput, 79.9}, {"dram", K::kBandwidth, 10}}, 100);
  EXPECT_EQ(b.kind, Bottleneck::Kind::kLatency) << describe(b);
  EXPECT_EQ(b.resource, "depth_test") << "the largest bound is named even when it does not bound the frame";
  EXPECT_EQ(format_bottleneck(b).rfind("latency: ", 0), 0u) << format_bottleneck(b);

  b = classify_bottleneck(
      {{"distributor", K::kThroughput, 90}, {"pixel_ordering", K::kThroughput, 90}, {"dram", K::kBandwidth, 0}}, 100);
  EXPECT_EQ(b.kind, Bottleneck::Kind::kThroughput) << describe(b);
  EXPECT_EQ(b.resource, "distributor") << "equal bounds: the first given";
  EXPECT_EQ(b.bounds.size(), 2u) << "a zero bound is dropped: " << describe(b);
  EXPECT_EQ(format_bottleneck(b).rfind("throughput (distributor): ", 0), 0u) << format_bottleneck(b);

  b = classify_bottleneck({}, 100);
  EXPECT_EQ(b.kind, Bottleneck::Kind::kLatency);
  EXPECT_TRUE(b.resource.empty());
}

// Each design names the kind and the resource it was built for, in the cycle
// model and in the analytical model; the named bound is the largest listed
// and, unless latency-bound, at least 80 % of the frame.
TEST(Bottleneck, DesignsOfEachKindInTheCycleAndApproximateFidelities) {
  const InputSpec in = scene("cloth", 16);
  for (const Case& c : cases()) {
    const CycleRun cyc = run_cycle(in, GoldenConfig{}, c.hw);
    const ApproxRun apx = run_approximate(in, GoldenConfig{}, c.hw);
    for (const auto& [fidelity, b] : {std::pair<const char*, const Bottleneck&>{"cycle", cyc.stats.bottleneck},
                                      std::pair<const char*, const Bottleneck&>{"approximate", apx.stats.bottleneck}}) {
      const std::string what = std::string(c.what) + ", " + fidelity + ": " + describe(b);
      EXPECT_EQ(b.kind, c.kind) << what;
      if (*c.resource) {
        EXPECT_EQ(b.resource, c.resource) << what;
      }
      ASSERT_FALSE(b.bounds.empty()) << what;
      EXPECT_EQ(b.bounds.front().cycles, b.bound_cycles) << what;
      if (c.kind != Bottleneck::Kind::kLatency) {
        EXPECT_GE(b.share(), kBoundShare) << what;
      } else {
        EXPECT_LT(b.share(), kBoundShare) << what;
      }
    }
    EXPECT_EQ(cyc.stats.memory_bound, c.kind == Bottleneck::Kind::kBandwidth) << c.what;
  }
}

// The cycle model's DRAM bound is its busiest channel's service: at least the
// data-bus cycles (bytes / bytes_per_clock), at most the run's cycles.
TEST(Bottleneck, TheDramBoundLiesBetweenTheBusCyclesAndTheRun) {
  const InputSpec in = scene("cloth", 16);
  for (const char* cfg : {"default", "narrow", "wide"}) {
    const CycleRun r = run_cycle(in, GoldenConfig{}, load_hw_config(kSource + "/configs/" + cfg + ".toml"));
    const DramStats& d = r.stats.dram;
    EXPECT_GE(d.max_channel_service, d.max_channel_busy) << cfg;
    EXPECT_LE(d.max_channel_service, r.stats.total_cycles) << cfg;
    double dram = -1;
    for (const ResourceBound& b : r.stats.bottleneck.bounds)
      if (b.name == "dram") dram = b.cycles;
    EXPECT_EQ(dram, double(d.max_channel_service)) << cfg << ": " << describe(r.stats.bottleneck);
  }
}

// The narrow design (one 16-byte channel, a small cache) without
// compression on a scene with depth complexity: both fidelities find the
// DRAM's bandwidth bounds it (with compression, 16 spp smoke moves so few
// bytes that the misses' latency does),
// the approximate model's own DRAM bound being nearly all of its estimate.
TEST(Bottleneck, TheNarrowDesignIsBandwidthBoundInBothFidelities) {
  const HwConfig hw = without_compression(load_hw_config(kSource + "/configs/narrow.toml"));
  const InputSpec in = scene("smoke", 16);
  const ApproxRun apx = run_approximate(in, GoldenConfig{}, hw);
  EXPECT_EQ(apx.stats.bottleneck.kind, Bottleneck::Kind::kBandwidth) << describe(apx.stats.bottleneck);
  EXPECT_EQ(apx.stats.bottleneck.resource, "dram") << describe(apx.stats.bottleneck);
  const CycleRun cyc = run_cycle(in, GoldenConfig{}, hw);
  EXPECT_EQ(cyc.stats.bottleneck.kind, Bottleneck::Kind::kBandwidth) << describe(cyc.stats.bottleneck);
  EXPECT_EQ(cyc.stats.bottleneck.resource, "dram") << describe(cyc.stats.bottleneck);
}

// A frame whose DRAM traffic is all write-backs (testcard's pixels fit the
// wide design's caches: nothing is read, the final flush writes every line)
// spends most of its cycles in that flush: the DRAM's service bounds it in
// both fidelities, though the analytical model's epoch bound for the DRAM
// counts only channels that served reads (write-backs are posted).
TEST(Bottleneck, AFrameEndingInItsFlushIsBandwidthBoundInBothFidelities) {
  // Without compression, whose state bits are read from DRAM.
  const HwConfig hw = without_compression(load_hw_config(kSource + "/configs/wide.toml"));
  const InputSpec in = scene("testcard", 16);
  const CycleRun cyc = run_cycle(in, GoldenConfig{}, hw);
  ASSERT_EQ(cyc.stats.dram.total_bytes_read(), 0u) << "the premise: the caches never evict";
  EXPECT_EQ(cyc.stats.bottleneck.kind, Bottleneck::Kind::kBandwidth) << describe(cyc.stats.bottleneck);
  const ApproxRun apx = run_approximate(in, GoldenConfig{}, hw);
  EXPECT_EQ(apx.stats.bottleneck.kind, Bottleneck::Kind::kBandwidth) << describe(apx.stats.bottleneck);
  EXPECT_EQ(apx.stats.bottleneck.resource, "dram") << describe(apx.stats.bottleneck);
  EXPECT_GE(double(apx.stats.dram_service_cycles), double(apx.stats.flush_cycles))
      << "the service of every burst includes the flush's";
}
