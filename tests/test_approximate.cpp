// The analytical timing model (--fidelity approximate, sim/fidelity/approximate/approximate.h)
// against the golden model (its image, bit for bit) and the cycle model (its
// DRAM bytes and total cycles, within the bounds stated here).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "sim/fidelity/approximate/approximate.h"
#include "sim/fidelity/cycle/cycle_run.h"
#include "sim/fidelity/functional/driver.h"
#include "tests/compare_util.h"
#include "util/errors.h"

using namespace ropsim;

namespace {

const std::string kSource = ROPSIM_SOURCE_DIR;

InputSpec scene(const std::string& name, int spp) {
  InputSpec in;
  in.scene.name = name;
  in.scene.spp = spp;
  return in;
}

GoldenConfig method(Method m) {
  GoldenConfig c;
  c.method = m;
  return c;
}

double rel(double a, double b) { return b != 0 ? (a - b) / b : (a == 0 ? 0.0 : 1.0); }

const char* const kConfigs[] = {"default", "narrow", "wide"};

HwConfig design(const std::string& name) { return load_hw_config(kSource + "/configs/" + name + ".toml"); }

}  // namespace

// The image comes from the functional pass: the golden image, bit for bit,
// with the golden model's counters, for single- and multi-pass methods.
TEST(Approximate, WritesTheGoldenImageBitForBit) {
  for (Method m : {Method::kLk, Method::kSlab, Method::kLkDepthAc, Method::kWboit, Method::kBlend}) {
    for (const char* s : {"cloth", "smoke"}) {
      const std::string what = std::string(s) + " 8 spp " + to_string(m);
      const InputSpec in = scene(s, 8);
      const FunctionalRun golden = run_functional(in, method(m));
      const ApproxRun a = run_approximate(in, method(m), HwConfig{});
      EXPECT_EQ(ropsim_test::first_image_difference(golden.image, a.image), "")
          << what << ": the approximate run's image is not the golden image";
      EXPECT_EQ(golden.counters.fragments, a.counters.fragments) << what;
      EXPECT_EQ(golden.counters.samples_written, a.counters.samples_written) << what;
      EXPECT_EQ(golden.counters.samples_blended, a.counters.samples_blended) << what;
      EXPECT_GT(a.stats.total_cycles, 0u) << what;
    }
  }
}

// The tag-only caches mirror the ROP caches (geometry, set index, LRU,
// write-allocate, fast clear, the flush): where the cycle model cannot
// reorder accesses to a line across an eviction -- a cache that holds the
// whole frame -- the DRAM bytes are the cycle model's exactly; elsewhere the
// pipeline's reordering (the depth test of later fragments reads before the
// writeback of earlier ones writes) moves them by at most 2.5 % (measured:
// 1.7 % at most, docs/results.md).
TEST(Approximate, DramBytesAreTheCycleModelsWhereTheTagsMustAgree) {
  {
    HwConfig hw = design("wide");  // 8 x 256 KiB: testcard's lines all fit, nothing is evicted
    const InputSpec in = scene("testcard", 16);
    const CycleRun c = run_cycle(in, method(Method::kLk), hw);
    const ApproxRun a = run_approximate(in, method(Method::kLk), hw);
    EXPECT_EQ(c.stats.dram.total_bytes_read(), a.stats.dram.total_bytes_read()) << "testcard on wide";
    EXPECT_EQ(c.stats.dram.total_bytes_written(), a.stats.dram.total_bytes_written()) << "testcard on wide";
    CacheStats cs;
    for (const auto& x : c.stats.caches) cs += x;
    EXPECT_EQ(cs.dirtied, a.stats.cache.dirtied) << "lines made dirty";
    EXPECT_EQ(cs.clear_fills, a.stats.cache.clear_fills) << "fast-clear fills";
  }
  for (const char* cfg : kConfigs)
    for (const char* s : {"cloth", "smoke"}) {
      const std::string what = std::string(s) + " 16 spp on " + cfg;
      const HwConfig hw = design(cfg);
      const InputSpec in = scene(s, 16);
      const CycleRun c = run_cycle(in, method(Method::kLk), hw);
      const ApproxRun a = run_approximate(in, method(Method::kLk), hw);
      EXPECT_LE(std::abs(rel(double(a.stats.dram.total_bytes_read()), double(c.stats.dram.total_bytes_read()))), 0.025)
          << what << ": DRAM bytes read " << a.stats.dram.total_bytes_read() << " vs the cycle model's "
          << c.stats.dram.total_bytes_read();
      EXPECT_LE(std::abs(rel(double(a.stats.dram.total_bytes_written()), double(c.stats.dram.total_bytes_written()))),
                0.025)
          << what << ": DRAM bytes written " << a.stats.dram.total_bytes_written() << " vs the cycle model's "
          << c.stats.dram.total_bytes_written();
    }
}

// Total cycles against the cycle model on the built-in scenes at 16 spp and
// the three designs: each within 15 % (the target for the mean), the
// mean within 6 % (measured 3.3 % over these 9, the largest 9.1 %: docs/results.md).
TEST(Approximate, TotalCyclesAreNearTheCycleModels) {
  double sum = 0;
  int n = 0;
  for (const char* cfg : kConfigs)
    for (const char* s : {"cloth", "smoke", "testcard"}) {
      const std::string what = std::string(s) + " 16 spp on " + cfg;
      const HwConfig hw = design(cfg);
      const InputSpec in = scene(s, 16);
      const CycleRun c = run_cycle(in, method(Method::kLk), hw);
      const ApproxRun a = run_approximate(in, method(Method::kLk), hw);
      const double e = rel(double(a.stats.total_cycles), double(c.stats.total_cycles));
      EXPECT_LE(std::abs(e), 0.15) << what << ": " << a.stats.total_cycles << " cycles vs the cycle model's "
                                   << c.stats.total_cycles << " (" << 100 * e << " %)";
      EXPECT_LE(a.stats.flush_cycles + a.stats.fill_cycles, a.stats.total_cycles) << what;
      EXPECT_GE(a.stats.total_cycles, uint64_t(a.stats.bound_cycles[int(ApproxBound::kSource)])) << what;
      sum += std::abs(e);
      ++n;
    }
  EXPECT_LE(sum / n, 0.06) << "mean absolute error " << 100 * sum / n << " %";
}

// Surface compression and Hi-Z (the default design): on an opaque
// scene the compressed design moves strictly fewer DRAM bytes than the same
// design with compression off (Hi-Z on in both), its compressed surfaces'
// writebacks move fewer bytes than uncompressed, and the image is still the
// golden image.
TEST(Approximate, CompressionMovesFewerDramBytesOnAnOpaqueScene) {
  const HwConfig hw = design("default");
  ASSERT_TRUE(hw.compression.depth && hw.compression.color && hw.hiz.enable)
      << "configs/default.toml no longer turns compression and Hi-Z on";
  HwConfig off = hw;
  off.compression.depth = off.compression.color = false;
  const InputSpec in = scene("opaque", 8);
  const GoldenConfig m = method(Method::kLk);
  const ApproxRun a = run_approximate(in, m, hw);
  const ApproxRun u = run_approximate(in, m, off);
  ASSERT_TRUE(a.stats.compression_on) << "the compressed run reports no compression";
  const CompressionTraffic& t = a.stats.compression;
  uint64_t moved = 0, uncompressed = 0;
  for (size_t b = 0; b < size_t(kBuffers); ++b) {
    moved += t.bytes_written[b];
    uncompressed += t.bytes_written_uncompressed[b];
  }
  EXPECT_GT(uncompressed, 0u) << "no compressed-surface line was written back";
  EXPECT_LT(moved, uncompressed) << "the opaque scene's tiles compress: their writebacks must move fewer bytes";
  const uint64_t with = a.stats.dram.total_bytes_read() + a.stats.dram.total_bytes_written();
  const uint64_t without = u.stats.dram.total_bytes_read() + u.stats.dram.total_bytes_written();
  EXPECT_LT(with, without) << "DRAM bytes with compression " << with << " (metadata included) are not fewer than "
                           << without << " without";
  EXPECT_GT(t.metadata_bytes_read[size_t(Buffer::kDepth)] + t.metadata_bytes_written[size_t(Buffer::kDepth)], 0u)
      << "the state bits cost no DRAM traffic";
  EXPECT_GT(t.hiz_tests, 0u) << "Hi-Z tested no fragment";
  EXPECT_EQ(ropsim_test::first_image_difference(a.image, run_functional(in, m).image), "")
      << "compression changed the image";
}

// The analytical model against the cycle model with compression and Hi-Z on
// (the default design), lk on the fidelity study's built-in scenes and
// the opaque one: total cycles and DRAM bytes (read + written) each within
// 15 % (the bound the fidelity asks of it; measured on all the fidelity
// study's inputs, the captured meshes too: docs/results.md), and the
// compressed bytes moved within 15 % too.
TEST(Approximate, WithCompressionAndHizIsWithinFifteenPercentOfTheCycleModel) {
  const HwConfig hw = design("default");
  for (const char* s : {"cloth", "smoke", "testcard", "opaque"}) {
    const std::string what = std::string(s) + " 16 spp on the default design";
    const InputSpec in = scene(s, 16);
    const CycleRun c = run_cycle(in, method(Method::kLk), hw);
    const ApproxRun a = run_approximate(in, method(Method::kLk), hw);
    const double e = rel(double(a.stats.total_cycles), double(c.stats.total_cycles));
    EXPECT_LE(std::abs(e), 0.15) << what << ": " << a.stats.total_cycles << " cycles vs the cycle model's "
                                 << c.stats.total_cycles << " (" << 100 * e << " %)";
    const double ab = double(a.stats.dram.total_bytes_read() + a.stats.dram.total_bytes_written());
    const double cb = double(c.stats.dram.total_bytes_read() + c.stats.dram.total_bytes_written());
    EXPECT_LE(std::abs(rel(ab, cb)), 0.15)
        << what << ": DRAM bytes " << ab << " vs the cycle model's " << cb << " (" << 100 * rel(ab, cb) << " %)";
    uint64_t am = 0, cm = 0;
    for (size_t b = 0; b < size_t(kBuffers); ++b) {
      am += a.stats.compression.bytes_written[b] + a.stats.compression.bytes_read[b];
      cm += c.stats.compression.bytes_written[b] + c.stats.compression.bytes_read[b];
    }
    EXPECT_LE(std::abs(rel(double(am), double(cm))), 0.15)
        << what << ": compressed-surface bytes moved " << am << " vs the cycle model's " << cm;
  }
}

// A compressed fill whose tile's state bits miss in the metadata cache
// requests its data only when they arrive, and a DRAM channel serves its
// bursts in order: the reads requested after it on its channel wait behind
// it. With a metadata cache of one line per ROP (every change of metadata
// line misses) on the wide design, the depth tests' waits are mostly that
// queueing; the model is held within 15 % of the cycle model there (measured
// -2.8 % and -9.0 %; requesting the data beside the metadata read came out
// 54 % and 55 % low).
TEST(Approximate, AFillWaitsForItsStateBitsAndTheChannelQueuesBehindIt) {
  HwConfig hw = design("wide");
  ASSERT_TRUE(hw.compression.depth && hw.compression.color) << "configs/wide.toml no longer compresses";
  hw.compression.metadata_cache_bytes = hw.cache.line_bytes;
  for (const char* s : {"cloth", "smoke"}) {
    const std::string what = std::string(s) + " 16 spp on wide with a one-line metadata cache";
    const InputSpec in = scene(s, 16);
    const CycleRun c = run_cycle(in, method(Method::kLk), hw);
    const ApproxRun a = run_approximate(in, method(Method::kLk), hw);
    ASSERT_GT(c.stats.compression.metadata_misses, 10000u) << what << ": the metadata cache must thrash";
    const double e = rel(double(a.stats.total_cycles), double(c.stats.total_cycles));
    EXPECT_LE(std::abs(e), 0.15) << what << ": " << a.stats.total_cycles << " cycles vs the cycle model's "
                                 << c.stats.total_cycles << " (" << 100 * e << " %)";
  }
}

// Inputs it cannot model are refused as user errors.
TEST(Approximate, RefusesTheReferenceMethod) {
  EXPECT_THROW(run_approximate(scene("testcard", 1), method(Method::kReference), HwConfig{}), UserError);
}
