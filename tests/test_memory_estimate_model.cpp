// The memory estimate's terms against the heap the cycle model allocates
// (rtl_models/top/memory_estimate.h; docs/config.md "Memory estimate"): each
// committed design's pipeline (and its compression model) is built, and the
// heap's growth (glibc mallinfo2: bytes in use, mmapped blocks included) is
// compared with the estimate (every term is one of those structures). The heap is
// measured exactly, so the bound is tight: 10 % (and 16 KiB). The whole process's peak
// resident memory is tests/test_memory_estimate.cpp's.
#include <gtest/gtest.h>
#include <malloc.h>

#include <array>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "rtl_models/algo/depth.h"
#include "rtl_models/config/hw_config.h"
#include "rtl_models/functional/fragment_source.h"
#include "rtl_models/functional/functional_rop.h"
#include "rtl_models/golden/golden_model.h"
#include "rtl_models/memory/compression_model.h"
#include "rtl_models/memory/line_set.h"
#include "rtl_models/top/memory_estimate.h"
#include "rtl_models/top/rop_pipeline.h"
#include "rtl_models/top/sim_context.h"
#include "tests/sanitizer.h"

namespace {

using namespace ropsim;

uint64_t heap_in_use() {
  const struct mallinfo2 m = mallinfo2();
  return uint64_t(m.uordblks) + uint64_t(m.hblkhd);
}

struct Design {
  std::string what;
  HwConfig hw;
};

std::vector<Design> designs() {
  std::vector<Design> d;
  for (const char* f : {"default", "narrow", "wide", "uncompressed"})
    d.push_back({f, load_hw_config(std::string(ROPSIM_SOURCE_DIR) + "/configs/" + f + ".toml")});
  d.push_back({"64 ROPs", resolve_hw_config("", {"distributor.rop_units=64"})});
  d.push_back(
      {"1 MiB caches of 16-byte lines", resolve_hw_config("", {"cache.size_bytes=1048576", "cache.line_bytes=16"})});
  return d;
}

constexpr double kSlack = 16384;

}  // namespace

// Every design's pipeline takes, on the heap, what its estimate says within
// 10 % and 16 KiB (the estimate counts the units' rings at the size they may
// grow to in a run, and rounds small objects), and holds the estimate's
// number of fragment tokens.
TEST(MemoryEstimateModel, BuiltPipelineHeapMatchesTheEstimate) {
#ifdef ROPSIM_TEST_ASAN
  GTEST_SKIP() << "AddressSanitizer's allocator does not report to glibc's mallinfo2: the normal build measures "
                  "the heap";
#endif
  // The first design is built twice: SystemC's and the libraries' one-time
  // allocations are not a pipeline's.
  std::vector<Design> ds = designs();
  ds.insert(ds.begin(), ds.front());
  for (size_t i = 0; i < ds.size(); ++i) {
    const Design& d = ds[i];
    SCOPED_TRACE(d.what);
    InputSpec in;
    in.scene.name = "smoke";
    in.scene.spp = 4;
    in.scene.width = 64;
    in.scene.height = 64;
    std::unique_ptr<FragmentSource> src = open_fragments(in);
    const TraceHeader header = src->header();
    GoldenConfig method;
    method.method = Method::kLk;
    FunctionalRop rop(header, method);
    rop.begin_pass(0);
    LineSet in_dram(d.hw.cache.line_bytes);
    const MemoryEstimate e = estimate_memory(d.hw, MemoryShape{header.width, header.height, header.spp, Method::kLk});
    FreshSimContext sim;
    const uint64_t before = heap_in_use();
    std::unique_ptr<CompressionModel> comp;
    if (d.hw.compression.any() || d.hw.hiz.enable) {
      std::array<uint32_t, kBuffers> bps{};
      bps[size_t(Buffer::kDepth)] = kDepthSampleBytes;
      bps[size_t(Buffer::kColor)] = kColorSampleBytes;
      comp = std::make_unique<CompressionModel>(d.hw, header.width, header.height, header.spp, bps,
                                                canonical_depth(header.clear_depth), d.hw.distributor.rop_units);
    }
    auto top = std::make_unique<RopPipeline>("top", std::move(src), rop, in_dram, d.hw);
    const uint64_t grown = heap_in_use() - before;
    if (i == 0) continue;
    const uint64_t estimated = e.model_bytes;
    std::printf("%-32s heap grown %10llu bytes, estimate %10llu bytes (%.3f)\n", d.what.c_str(),
                (unsigned long long)grown, (unsigned long long)estimated, double(estimated) / double(grown));
    EXPECT_NEAR(double(grown), double(estimated), 0.10 * double(estimated) + kSlack)
        << "building the pipeline took " << grown << " bytes of heap, its estimate's terms say " << estimated;
    EXPECT_EQ(top->tokens().allocated(), e.tokens) << "the pipeline's tokens are not the estimate's";
    EXPECT_EQ(top->token_bound(), e.tokens);
    top.reset();
  }
}
