// Memory follows what a scene touches (util/memory_budget.h, docs/testing.md
// "Memory"): the per-sample state, the resolved image and the A-buffer
// reference are held per touched tile; what grows is charged against
// --memory-limit, and going over is one line, exit 1, no output -- never
// std::bad_alloc.
#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <string>

#include "rtl_models/golden/golden_model.h"
#include "tests/sanitizer.h"
#include "tests/study_test_util.h"
#include "util/errors.h"
#include "util/memory_budget.h"

namespace {

using namespace ropsim_test;
using ropsim::memory_budget;
using ropsim::parse_memory_size;

// "none" is the one spelling of no limit: a zero size in any unit and ""
// are refused alike, naming the flag.
TEST(MemoryBudget, SizesParseAsBinaryUnitsPercentagesOrNone) {
  EXPECT_EQ(parse_memory_size("1024", "--memory-limit"), 1024u);
  EXPECT_EQ(parse_memory_size("512M", "--memory-limit"), 512ull << 20);
  EXPECT_EQ(parse_memory_size("2G", "--memory-limit"), 2ull << 30);
  EXPECT_EQ(parse_memory_size("3GiB", "--memory-limit"), 3ull << 30);
  EXPECT_EQ(parse_memory_size("64k", "--memory-limit"), 64ull << 10);
  EXPECT_EQ(parse_memory_size("none", "--memory-limit"), 0u);
  const uint64_t half = parse_memory_size("50%", "--memory-limit"), all = parse_memory_size("100%", "--memory-limit");
  EXPECT_GT(half, 0u);
  EXPECT_NEAR(double(half) / double(all), 0.5, 1e-6);
  EXPECT_NEAR(double(ropsim::default_memory_limit()) / double(all), 0.8, 1e-3) << "the default is 80 % of memory";
  for (const char* bad : {"", "0", "0M", "0K", "M", "12X", "-1", "1.5G", "0%", "101%", "99999999999T", "12 M"}) {
    try {
      (void)parse_memory_size(bad, "--memory-limit");
      ADD_FAILURE() << "accepted \"" << bad << "\"";
    } catch (const ropsim::UserError& e) {
      EXPECT_NE(std::string(e.what()).find("--memory-limit"), std::string::npos) << e.what();
    }
  }
}

TEST(MemoryBudget, AChargeOverTheLimitIsRefusedAndTakesNothing) {
  ropsim::MemoryBudget b;
  b.set_limit(1000);
  b.charge(600, "a");
  EXPECT_THROW(b.charge(500, "the test's state"), ropsim::UserError);
  EXPECT_EQ(b.used(), 600u) << "a refused charge must take nothing";
  b.charge(400, "b");  // exactly the limit is allowed
  EXPECT_EQ(b.peak(), 1000u);
  b.release(1000);
  EXPECT_EQ(b.used(), 0u);
  try {
    b.charge(2000, "the test's state");
    ADD_FAILURE() << "not refused";
  } catch (const ropsim::UserError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("the test's state"), std::string::npos) << m;
    EXPECT_NE(m.find("--memory-limit 1000 B"), std::string::npos) << m;
  }
}

// A model, its image and the reference give back what they took when they go
// (a study worker runs many points in one process).
TEST(MemoryBudget, ModelsAndImagesReleaseTheirShare) {
  const uint64_t before = memory_budget().used();
  {
    ropsim::TraceHeader h;
    h.width = 300;
    h.height = 200;
    h.spp = 16;
    for (ropsim::Method m : {ropsim::Method::kLk, ropsim::Method::kReference}) {
      ropsim::GoldenConfig cfg;
      cfg.method = m;
      auto model = ropsim::make_functional_model(h, cfg);
      for (uint32_t i = 0; i < 5000; ++i) {
        ropsim::Fragment f;
        f.x = (i * 37) % h.width;
        f.y = (i * 11) % h.height;
        f.coverage = 0xFFFF;
        f.z0 = 0.5f;
        f.alpha = 0.5f;
        f.rgb = {1, 0, 0};
        model->draw(f);
      }
      const ropsim::Image img = model->resolve();
      EXPECT_GT(memory_budget().used(), before + img.bytes() / 2) << "nothing was charged";
      EXPECT_LT(img.tiles(), size_t(38 * 25) + 1);
    }
  }
  EXPECT_EQ(memory_budget().used(), before) << "a model or image kept its share after it was destroyed";
}

/// The report's number at a dotted path.
double report_number(const fs::path& p, const std::string& a, const std::string& b) {
  const auto j = nlohmann::json::parse(slurp(p));
  return j.at(a).at(b).get<double>();
}

// The fuzz regression trace whose header says 32768 x 32768 (576 fragments in
// 64 pixels): before, the functional run needed 12 GiB and the cycle model
// more. Both fidelities now run it, writing the report, in well under 256 MB
// of resident memory (measured by ropsim itself: VmHWM, host.peak_rss_bytes).
TEST(Memory, AHugeScreenWithFewFragmentsRunsInBothFidelitiesInLittleMemory) {
  Scratch s("memory-huge");
  const std::string trace = std::string(ROPSIM_SOURCE_DIR) + "/fuzz/regressions/trace/screen-32768-squared.rtrace";
  for (const char* fid : {"functional", "cycle"}) {
    const Ran r =
        ropsim_test::ropsim(s.dir, "run --trace '" + trace + "' --fidelity " + fid + " --report r.json --quiet", 300);
    ASSERT_EQ(r.status, 0) << fid << ": " << r.err;
    const double rss = report_number(s.dir / "r.json", "host", "peak_rss_bytes");
    EXPECT_GT(rss, 0) << fid;
#ifndef ROPSIM_TEST_ASAN  // AddressSanitizer's shadow memory and quarantine are resident too
    EXPECT_LT(rss, 256.0 * (1 << 20)) << fid << ": peak resident memory " << rss / (1 << 20) << " MiB";
#endif
    EXPECT_LT(report_number(s.dir / "r.json", "host", "memory_charged_peak_bytes"), 8.0 * (1 << 20))
        << fid << ": the state charged should be a few tiles and the directory";
  }
}

TEST(Memory, AStateOverTheLimitIsOneLineExitOneAndNoOutput) {
  Scratch s("memory-over");
  for (const std::string fid : {"functional", "cycle"}) {
    const Ran r = ropsim_test::ropsim(
        s.dir,
        "run --scene cloth --spp 16 --fidelity " + fid + " --memory-limit 256K --out o.png --report r.json --quiet",
        120);
    EXPECT_EQ(r.status, 1) << fid << ": " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << fid << ": not one line:\n" << r.err;
    EXPECT_EQ(r.err.rfind("ropsim: error: memory limit: ", 0), 0u) << fid << ": " << r.err;
    EXPECT_NE(r.err.find("--memory-limit 256.0 KiB"), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("bad_alloc"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(s.dir / "o.png")) << fid;
    EXPECT_FALSE(fs::exists(s.dir / "r.json")) << fid;
  }
  // The same run within a limit that fits it succeeds (the limit is what refused it).
  const Ran ok =
      ropsim_test::ropsim(s.dir, "--memory-limit 256M run --scene cloth --spp 16 --report r.json --quiet", 120);
  EXPECT_EQ(ok.status, 0) << ok.err;
  EXPECT_EQ(report_number(s.dir / "r.json", "host", "memory_limit_bytes"), double(256 << 20));
}

// The A-buffer grows with the fragments: an uncompressed trace tells their
// number up front, so the run is refused before any work; a compressed one is
// refused as its lists grow. Either way one line, exit 1, no report.
TEST(Memory, TheReferenceObeysTheLimitUpFrontOrAsItGrows) {
  Scratch s("memory-reference");
  ASSERT_EQ(ropsim_test::ropsim(s.dir, "scene cloth --spp 4 --compression none -o plain.rtrace").status, 0);
  ASSERT_EQ(ropsim_test::ropsim(s.dir, "scene cloth --spp 4 --compression zstd -o packed.rtrace").status, 0);
  struct Case {
    const char* trace;
    const char* says;
  } cases[] = {{"plain.rtrace", "is estimated to need"}, {"packed.rtrace", "grew to"}};
  for (const Case& c : cases) {
    const Ran r = ropsim_test::ropsim(
        s.dir, std::string("run --trace ") + c.trace + " --method reference --memory-limit 2M --report r.json --quiet",
        120);
    EXPECT_EQ(r.status, 1) << c.trace << ": " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(c.says), std::string::npos) << c.trace << ": " << r.err;
    EXPECT_NE(r.err.find("A-buffer reference"), std::string::npos) << c.trace << ": " << r.err;
    EXPECT_FALSE(fs::exists(s.dir / "r.json"));
  }
  const Ran ok = ropsim_test::ropsim(
      s.dir, "run --trace plain.rtrace --vs-reference --memory-limit 64M --report r.json --quiet", 120);
  EXPECT_EQ(ok.status, 0) << ok.err;
}

}  // namespace
