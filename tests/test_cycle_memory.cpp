// The memory side of the cycle model in a run: the address map's line walk,
// and the depth lines the depth test reads against the golden model's
// depth-read counters.
#include "tests/cycle_test_util.h"

using namespace ropsim;
using namespace cycle_test;

// The line walk of the address map visits exactly the lines that hold a
// sample of the mask, in increasing order, once each, for every sample size
// a surface takes: a frame without draw states (depth 4, colour 6, accum
// RGBA16F 8), an 8-bit frame (colour RGBA8 4) and blend's float framebuffer
// (16).
TEST(AddressMapLines, LineWalkMatchesAPerSampleWalk) {
  std::mt19937_64 rng(3);
  SampleBytes rgba8 = plain_sample_bytes(), float_fb = plain_sample_bytes();
  rgba8[size_t(Buffer::kColor)] = rgba8[size_t(Buffer::kAccum)] = 4;
  float_fb[size_t(Buffer::kAccum)] = 16;
  for (const SampleBytes& sizes : {plain_sample_bytes(), rgba8, float_fb})
    for (int spp : {1, 4, 8, 16, 32, 64})
      for (uint32_t line : {16u, 32u, 64u, 128u})
        for (Buffer b : {Buffer::kDepth, Buffer::kColor, Buffer::kAccum}) {
          AddressMap am(40, spp, 3, line, sizes);
          for (int trial = 0; trial < 40; ++trial) {
            const uint32_t x = uint32_t(rng() % 40), y = uint32_t(rng() % 40);
            uint64_t mask = rng() & (spp == 64 ? ~0ull : (1ull << spp) - 1);
            if (trial == 0) mask = spp == 64 ? ~0ull : (1ull << spp) - 1;
            std::vector<uint64_t> got, want;
            am.for_each_sample_line(b, x, y, mask, [&](uint64_t l) { got.push_back(l); });
            const uint64_t bps = sizes[size_t(b)];
            const uint64_t start = AddressMap::base(b) + am.pixel_index(x, y) * uint64_t(spp) * bps;
            for (int s = 0; s < spp; ++s)
              if (mask >> s & 1)
                for (uint64_t a = start + uint64_t(s) * bps; a < start + uint64_t(s + 1) * bps; ++a) {
                  const uint64_t l = a / line * line;
                  if (want.empty() || want.back() != l) want.push_back(l);
                }
            EXPECT_EQ(got, want) << "spp " << spp << " line " << line << " " << to_string(b) << " of " << bps
                                 << " bytes mask " << mask;
          }
        }
}

// ------------------------------------------------------------ depth reads, both fidelities

namespace {

/// The methods with a ROP pipeline (every method but the reference).
std::vector<Method> pipeline_methods() {
  std::vector<Method> v;
  for (const auto& t : kMethodTable)
    if (t.pipeline) v.push_back(t.method);
  return v;
}

/// The golden model's run of in (every pass): its counters and the
/// fragments (every pass) it charged a depth read.
struct GoldenReads {
  Counters counters;
  uint64_t fragments_read = 0;
};
GoldenReads golden_reads(const InputSpec& in, const GoldenConfig& cfg) {
  const FragmentList list = load_fragments(in);
  StochasticModel golden(list.header, cfg);
  GoldenReads r;
  golden.set_counts_observer(
      [&](size_t, const FragWork&, const Counters& d) { r.fragments_read += d.depth_bytes_read > 0; });
  for (int pass = 0; pass < golden.passes(); ++pass) {
    golden.begin_pass(pass);
    golden.draw_batch(list.fragments.data(), list.fragments.size());
  }
  r.counters = golden.counters();
  return r;
}

/// The depth lines the cycle model's depth tests asked their caches for.
uint64_t depth_line_reads(const CycleRun& run) {
  CacheStats c;
  for (const auto& x : run.stats.caches) c += x;
  return c.read_hits[size_t(Buffer::kDepth)] + c.read_misses[size_t(Buffer::kDepth)];
}

}  // namespace

// A scene whose fragments the coverage selection discards all (alpha 0:
// a2c's k, hashed's test and hashed-a2c's thresholds keep no sample) reads
// no depth in either fidelity: the functional counters charge none, and the
// cycle model's depth test asks its cache for no depth line.
TEST(DepthReads, AllDiscardedReadsNoDepthInEitherFidelity) {
  TraceHeader h = small_header(4);
  const std::string path = ::testing::TempDir() + "/discarded.rtr";
  {
    TraceWriter w(path, h);
    for (uint32_t layer = 0; layer < 2; ++layer)
      for (uint32_t y = 0; y < 64; ++y)
        for (uint32_t x = 0; x < 64; ++x) {
          Fragment f;
          f.x = uint16_t(x);
          f.y = uint16_t(y);
          f.coverage = 0xF;
          f.z0 = 0.25f + 0.5f * float(layer);
          f.alpha = 0.0f;
          f.rgb = {1, 1, 1};
          f.prim_id = x + 64 * y;
          f.draw_id = layer;
          w.write(f);
        }
    w.finish();
  }
  InputSpec in;
  in.trace_path = path;
  for (Method m : {Method::kA2c, Method::kHashed, Method::kHashedA2c}) {
    const GoldenReads g = golden_reads(in, method_config(m));
    EXPECT_EQ(g.counters.fragments, 2u * 64 * 64) << to_string(m);
    EXPECT_EQ(g.counters.depth_bytes_read, 0u) << to_string(m) << ": the functional counters charge a depth read";
    EXPECT_EQ(g.counters.state_bytes_read(), 0u) << to_string(m);
    const CycleRun cyc = run_cycle(in, method_config(m), HwConfig{});
    EXPECT_EQ(depth_line_reads(cyc), 0u) << to_string(m) << ": the cycle model read depth";
  }
}

// Per method, the fragments the golden model charges a depth read are the
// ones the cycle model's depth test reads: on the foliage (75 % of its
// fragments at alpha exactly 0 or 1) at 1 and 4 spp, a pixel's depth samples
// lie in one 64-byte line, so the cycle model reads one depth line per
// fragment it reads at all, and at 1 spp one per 4 bytes the golden model
// charges. slab reads its layers, no depth, in both.
TEST(DepthReads, BothFidelitiesReadTheDepthOfTheSameFragments) {
  // Without Hi-Z, which rejects fragments before their depth read.
  const HwConfig hw = load_hw_config(kSource + "/configs/uncompressed.toml");
  ASSERT_EQ(hw.cache.line_bytes, 64u) << "the test assumes a pixel's 4-spp depths in one line";
  for (int spp : {1, 4}) {
    InputSpec in = scene_input("foliage", spp);
    in.scene.width = in.scene.height = 64;
    for (Method m : pipeline_methods()) {
      const std::string what = std::string(to_string(m)) + " at " + std::to_string(spp) + " spp";
      const GoldenReads g = golden_reads(in, method_config(m));
      const CycleRun cyc = run_cycle(in, method_config(m), hw);
      const uint64_t lines = depth_line_reads(cyc);
      EXPECT_EQ(g.fragments_read, lines) << what << ": fragments charged a depth read against depth lines read";
      if (spp == 1) {
        EXPECT_EQ(g.counters.depth_bytes_read, 4 * lines) << what;
      }
      if (m == Method::kSlab)
        EXPECT_EQ(lines, 0u) << what;
      else
        EXPECT_GT(lines, 0u) << what << ": the test needs depth reads";
    }
  }
}
