// The cycle-approximate SystemC pipeline: bit-exactness against the golden
// model over every built-in scene x spp x method x config, each unit alone
// with a scripted source and sink (latency at its boundary, throughput), the
// pixel-ordering guarantee, the hardware config, and timing that behaves like
// hardware (ROP scaling, memory-bound runs, linear cost in the work).
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zstd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <thread>

#include "rtl_models/algo/compression.h"
#include "rtl_models/algo/sort_order.h"
#include "rtl_models/config/hw_config.h"
#include "rtl_models/functional/fragment_source.h"
#include "rtl_models/golden/golden_model.h"
#include "rtl_models/memory/address_map.h"
#include "rtl_models/observe/waveform.h"
#include "rtl_models/top/sim_context.h"
#include "rtl_models/units/alpha_ref_gen.h"
#include "rtl_models/units/blend_unit.h"
#include "rtl_models/units/coverage_tracker.h"
#include "rtl_models/units/depth_test.h"
#include "rtl_models/units/rop_ownership.h"
#include "rtl_models/units/sample_sorter.h"
#include "rtl_models/units/writeback.h"
#include "sim/fidelity/approximate/approximate.h"
#include "sim/fidelity/cycle/cycle_run.h"
#include "sim/fidelity/functional/driver.h"
#include "sim/fidelity/sampled/livepoint_file.h"
#include "sim/fidelity/sampled/livepoints.h"
#include "sim/report/cycle_report.h"
#include "tests/vcd_reader.h"
#include "traces/raster/rasterizer.h"
#include "traces/raster/sample_patterns.h"
#include "util/errors.h"

using namespace ropsim;

namespace {

const std::string kSource = ROPSIM_SOURCE_DIR;

/// hw without compression and Hi-Z (as configs/uncompressed.toml).
HwConfig without_compression(HwConfig hw) {
  for (const char* a : {"compression.depth=false", "compression.color=false", "hiz.enable=false"})
    apply_hw_override(hw, a);
  return hw;
}

std::vector<std::string> config_files() {
  std::vector<std::string> v;
  for (const auto& e : std::filesystem::directory_iterator(kSource + "/configs"))
    if (e.path().extension() == ".toml") v.push_back(e.path().string());
  std::sort(v.begin(), v.end());
  return v;
}

/// The designs of the per-design timing tests: every committed design but
/// uncompressed.toml (the default without compression and Hi-Z), which
/// BitExactCompression.TheUncompressedBaselineMatchesTheGoldenModel runs on a
/// smaller matrix (CI budget).
std::vector<std::string> timing_config_files() {
  std::vector<std::string> v;
  for (const auto& f : config_files())
    if (std::filesystem::path(f).filename() != "uncompressed.toml") v.push_back(f);
  return v;
}

GoldenConfig method_config(Method m, const BlendFormats& formats = {},
                           EndertonSelection sel = EndertonSelection::kDepthFirst) {
  GoldenConfig c;
  c.method = m;
  c.formats = formats;
  c.enderton_selection = sel;
  return c;
}

void expect_bit_exact(const TraceHeader& header, const std::vector<Fragment>& frags, const GoldenConfig& cfg,
                      const HwConfig& hw, const std::string& what, bool lockstep,
                      const std::function<CycleRun(const CycleOptions&)>& cycle);

/// Golden and cycle runs of one input; fails naming the first difference in
/// the full per-sample state, the image or the counters. A multi-pass method
/// replays the input once per pass in both.
void expect_bit_exact(const InputSpec& in, const GoldenConfig& cfg, const HwConfig& hw, const std::string& what,
                      bool lockstep = false) {
  const FragmentList list = load_fragments(in);
  expect_bit_exact(list.header, list.fragments, cfg, hw, what, lockstep,
                   [&](const CycleOptions& opt) { return run_cycle(in, cfg, hw, opt); });
}

/// The same for fragments held in memory (their header's draw states included).
void expect_bit_exact(const TraceHeader& h, const std::vector<Fragment>& frags, const GoldenConfig& cfg,
                      const HwConfig& hw, const std::string& what, bool lockstep = false) {
  expect_bit_exact(h, frags, cfg, hw, what, lockstep, [&](const CycleOptions& opt) {
    return run_cycle([&] { return fragments_from(h, frags); }, cfg, hw, opt);
  });
}

void expect_bit_exact(const TraceHeader& header, const std::vector<Fragment>& frags, const GoldenConfig& cfg,
                      const HwConfig&, const std::string& what, bool lockstep,
                      const std::function<CycleRun(const CycleOptions&)>& cycle) {
  StochasticModel golden(header, cfg);
  for (int pass = 0; pass < golden.passes(); ++pass) {
    golden.begin_pass(pass);
    for (const auto& f : frags) golden.draw(f);
  }
  CycleOptions opt;
  opt.lockstep = lockstep;
  const CycleRun cyc = cycle(opt);
  const std::string diff = first_state_difference(golden.store(), *cyc.state);
  EXPECT_EQ(diff, "") << what << ": the cycle model's final state differs from the golden model's";
  EXPECT_TRUE(golden.resolve() == cyc.image) << what << ": resolved images differ";
  const Counters& a = golden.counters();
  const Counters& b = cyc.counters;
  EXPECT_EQ(a.fragments, b.fragments) << what;
  EXPECT_EQ(a.samples_tested, b.samples_tested) << what;
  EXPECT_EQ(a.samples_depth_passed, b.samples_depth_passed) << what;
  EXPECT_EQ(a.samples_opacity_passed, b.samples_opacity_passed) << what;
  EXPECT_EQ(a.samples_written, b.samples_written) << what;
  EXPECT_EQ(a.surface_id_changes, b.surface_id_changes) << what;
  EXPECT_EQ(a.sorts, b.sorts) << what;
  EXPECT_EQ(a.tracker_bytes_written, b.tracker_bytes_written) << what;
  EXPECT_EQ(a.layer_bytes_written, b.layer_bytes_written) << what;
  EXPECT_EQ(a.samples_blended, b.samples_blended) << what;
  EXPECT_EQ(a.target_bytes_written, b.target_bytes_written) << what;
  EXPECT_EQ(a.depth_bytes_written, b.depth_bytes_written) << what;
  EXPECT_GT(cyc.stats.total_cycles, 0u) << what;
}

/// The same for method m with the design's render-target formats.
void expect_bit_exact(const InputSpec& in, Method m, const HwConfig& hw, const std::string& what, bool lockstep = false,
                      EndertonSelection sel = EndertonSelection::kDepthFirst) {
  expect_bit_exact(in, method_config(m, hw.blend.formats, sel), hw, what, lockstep);
}

InputSpec scene_input(const std::string& name, int spp, uint32_t repeat = 1) {
  InputSpec in;
  in.scene.name = name;
  in.scene.spp = spp;
  in.repeat = repeat;
  return in;
}

}  // namespace

// ------------------------------------------------------------ bit-exactness

class BitExact : public ::testing::TestWithParam<std::tuple<std::string, std::string>> {};

TEST_P(BitExact, EveryMethodAndSppMatchesTheGoldenModel) {
  const auto& [scene, config] = GetParam();
  const HwConfig hw = load_hw_config(config);
  for (int spp : {1, 4, 16, 64})
    for (Method m : {Method::kOpaque, Method::kA2c, Method::kEnderton, Method::kLk, Method::kHashed, Method::kHashedA2c,
                     Method::kSlab, Method::kWboit, Method::kLkAc, Method::kLkDepth, Method::kLkDepthAc,
                     Method::kEndertonAc, Method::kEndertonDepth, Method::kEndertonDepthAc, Method::kBlend})
      expect_bit_exact(scene_input(scene, spp), m, hw,
                       scene + " " + std::to_string(spp) + " spp " + to_string(m) + " on " + config);
}

INSTANTIATE_TEST_SUITE_P(AllScenesAllConfigs, BitExact,
                         ::testing::Combine(::testing::Values("testcard", "eight-layers", "enderton-1", "enderton-2",
                                                              "cloth", "smoke", "opaque", "foliage"),
                                            ::testing::ValuesIn(timing_config_files())),
                         [](const auto& info) {
                           std::string s = std::get<0>(info.param) + "_" +
                                           std::filesystem::path(std::get<1>(info.param)).stem().string();
                           for (char& c : s)
                             if (!isalnum(static_cast<unsigned char>(c))) c = '_';
                           return s;
                         });

namespace {

/// A frame of mixed draw states (blend's test input): 24 x 20 pixels, eight
/// draws of overlapping rectangles with sloped depth and partial coverage,
/// drawn with blending off and on (src-over, additive, multiply, MIN/MAX,
/// constant colour, SRC_ALPHA_SATURATE), depth functions LESS, GREATER,
/// LEQUAL, ALWAYS and off, writes on and off, a colour mask; every draw into
/// a target of encoding e. Fixed seed.
std::pair<TraceHeader, std::vector<Fragment>> mixed_state_frame(int spp, TargetEncoding e) {
  using F = BlendFactor;
  using Q = BlendEquation;
  std::vector<DrawState> d(8);
  for (uint32_t i = 0; i < 8; ++i) {
    d[i] = default_draw_state(i);
    d[i].encoding = e;
  }
  d[0].blend = false;  // opaque, LESS, writing
  d[0].depth_write = true;
  d[1].depth_test = false;  // src-over with its depth test off (a HUD)
  d[2].src_rgb = F::kOne;   // additive
  d[2].dst_rgb = F::kOne;
  d[3].src_rgb = F::kDstColor;  // multiply, GREATER
  d[3].dst_rgb = F::kZero;
  d[3].depth_func = DepthFunc::kGreater;
  d[4].eq_rgb = Q::kMin;  // MIN / MAX, depth test off
  d[4].eq_alpha = Q::kMax;
  d[4].depth_test = false;
  d[4].depth_write = true;           // (no effect with the test off)
  d[5].src_rgb = F::kConstantColor;  // constant colour, LEQUAL, writing, colour mask
  d[5].dst_rgb = F::kOneMinusConstantAlpha;
  d[5].blend_color = {0.3f, 0.6f, 0.9f, 0.25f};
  d[5].depth_func = DepthFunc::kLequal;
  d[5].depth_write = true;
  d[5].color_mask = 0xB;
  d[6].src_rgb = F::kSrcAlphaSaturate;  // saturate, reverse subtract, ALWAYS
  d[6].dst_rgb = F::kDstAlpha;
  d[6].eq_rgb = Q::kReverseSubtract;
  d[6].depth_func = DepthFunc::kAlways;
  d[7].blend = false;  // opaque again, late, writing
  d[7].depth_write = true;
  TraceHeader h;
  h.width = 24;
  h.height = 20;
  h.spp = spp;
  h.positions = standard_sample_positions(spp);
  h.clear_color = {0.1f, 0.2f, 0.3f};
  h.draws = DrawTable(d);
  std::mt19937 rng(7);
  auto unit = [&rng] { return float(rng() >> 8) / float(1u << 24); };
  std::vector<Fragment> frags;
  const uint64_t all = spp == 64 ? ~0ull : (1ull << spp) - 1;
  for (uint32_t draw = 0; draw < 8; ++draw)
    for (int rect = 0; rect < 3; ++rect) {
      const uint32_t x0 = rng() % 16, y0 = rng() % 12, w = 4 + rng() % 8, hh = 4 + rng() % 8;
      const float z = 0.2f + 0.6f * unit(), dz = 0.02f * (unit() - 0.5f);
      const std::array<float, 3> rgb = {unit(), unit(), unit()};
      const float alpha = unit();
      for (uint32_t y = y0; y < std::min(h.height, y0 + hh); ++y)
        for (uint32_t x = x0; x < std::min(h.width, x0 + w); ++x) {
          Fragment f;
          f.draw_id = draw;
          f.prim_id = uint32_t(rect);
          f.x = uint16_t(x);
          f.y = uint16_t(y);
          f.coverage = (x == x0 || y == y0) ? all & 0x5555555555555555ull : all;
          if (!f.coverage) f.coverage = 1;
          f.z0 = draw == 5 ? 0.5f : z + dz * float(x - x0);  // draw 5 meets draw 0's plane exactly sometimes
          f.rgb = rgb;
          f.alpha = alpha;
          frags.push_back(f);
        }
    }
  return {h, frags};
}

}  // namespace

TEST(BitExactBlend, MixedDrawStatesMatchTheGoldenModelInEveryEncoding) {
  // blend on a frame of mixed draw states (every equation family, depth
  // function and mask), golden against cycle, on every committed design
  // (the default's compression and Hi-Z included), lockstep too.
  std::vector<HwConfig> designs;
  for (const auto& config : config_files()) designs.push_back(load_hw_config(config));
  for (const HwConfig& hw : designs)
    for (TargetEncoding e : {TargetEncoding::kUnorm8, TargetEncoding::kSrgb8, TargetEncoding::kFloat})
      for (int spp : {1, 4, 16}) {
        const auto [h, frags] = mixed_state_frame(spp, e);
        const std::string what =
            std::string("blend ") + to_string(e) + " " + std::to_string(spp) + " spp on " + hw.name;
        expect_bit_exact(h, frags, method_config(Method::kBlend, hw.blend.formats), hw, what);
        if (spp == 4) expect_bit_exact(h, frags, method_config(Method::kBlend, hw.blend.formats), hw, what, true);
      }
}

TEST(BitExactBlend, AnEightBitTargetMovesItsColourAsRgba8) {
  // The cycle model's address map and DRAM traffic use the surfaces' bytes
  // in memory (surface_bytes.h): on the mixed frame at 16 spp an 8-bit
  // target's colour (lk) and framebuffer (blend) move fewer bytes than the
  // same frame's float target (6 and 16 bytes a sample), with the same
  // fragments and samples; the ROP writes the same depth bytes. (Depth's
  // DRAM bytes may differ: the caches are shared by the surfaces, so a
  // smaller colour surface changes which depth lines are evicted and
  // written twice.)
  for (Method m : {Method::kBlend, Method::kLk}) {
    const Buffer b = m == Method::kBlend ? Buffer::kAccum : Buffer::kColor;
    std::array<uint64_t, 2> written{}, depth{}, samples{};
    for (TargetEncoding e : {TargetEncoding::kUnorm8, TargetEncoding::kFloat}) {
      const auto frame = mixed_state_frame(16, e);
      const CycleRun r =
          run_cycle([&] { return fragments_from(frame.first, frame.second); }, method_config(m), HwConfig{});
      const size_t i = e == TargetEncoding::kFloat;
      written[i] = r.stats.dram.bytes_written[size_t(b)];
      depth[i] = r.counters.depth_bytes_written;
      samples[i] = r.counters.samples_tested;
    }
    const std::string what = std::string(to_string(m)) + "'s " + to_string(b);
    EXPECT_GT(written[0], 0u) << what;
    EXPECT_LT(written[0], written[1]) << what << ": unorm8 against float";
    EXPECT_EQ(samples[0], samples[1]) << to_string(m) << ": the same samples tested";
    EXPECT_GT(depth[0], 0u) << to_string(m);
    EXPECT_EQ(depth[0], depth[1]) << to_string(m) << ": depth is binary32 in both";
  }
}

TEST(BitExactBlend, TheFrameExercisesEveryPathOfTheRule) {
  // The mixed frame is worth its name: some samples fail their depth test,
  // some depths are written, and the result differs between the encodings.
  const auto [h, frags] = mixed_state_frame(4, TargetEncoding::kUnorm8);
  StochasticModel m(h, method_config(Method::kBlend));
  for (const auto& f : frags) m.draw(f);
  const Counters c = m.counters();
  EXPECT_LT(c.samples_depth_passed, c.samples_tested);
  EXPECT_GT(c.depth_bytes_written, 0u);
  const auto [hf, ff] = mixed_state_frame(4, TargetEncoding::kFloat);
  StochasticModel mf(hf, method_config(Method::kBlend));
  for (const auto& f : ff) mf.draw(f);
  EXPECT_FALSE(m.resolve() == mf.resolve());
}

TEST(BitExactDrawRoutes, EverySinglePassMethodOnMixedDrawStatesMatchesTheGoldenModel) {
  // The per-sample single-pass methods on the mixed frame: its opaque draws
  // (z-buffer writes), blended draws (read-modify-writes of the colour) and
  // src-over draws (the method's) through one pipeline, whose units pass the
  // first two through; every committed design (Hi-Z and compression
  // included), unorm8 and float, lockstep once.
  std::vector<HwConfig> designs;
  for (const auto& config : config_files()) designs.push_back(load_hw_config(config));
  for (const HwConfig& hw : designs)
    for (TargetEncoding e : {TargetEncoding::kUnorm8, TargetEncoding::kFloat})
      for (int spp : {4, 16}) {
        const auto [h, frags] = mixed_state_frame(spp, e);
        for (Method m : {Method::kLk, Method::kEnderton, Method::kNaive, Method::kA2c, Method::kHashed,
                         Method::kHashedA2c, Method::kOpaque}) {
          const std::string what =
              std::string(to_string(m)) + " " + to_string(e) + " " + std::to_string(spp) + " spp on " + hw.name;
          expect_bit_exact(h, frags, method_config(m, hw.blend.formats), hw, what,
                           m == Method::kLk && spp == 4 && e == TargetEncoding::kUnorm8);
        }
      }
}

TEST(BitExactDrawRoutes, ThePrepassMethodsOnMixedDrawStatesMatchTheGoldenModel) {
  // wboit, slab, +ac, +depth and +depth+ac on the mixed frame: a pre-pass
  // of its opaque and blended draws, then their own passes over its src-over
  // draws (+ac's colour into the accumulation target, +depth's mark into the
  // transmittance target); every committed design, unorm8 and float,
  // lockstep once.
  std::vector<HwConfig> designs;
  for (const auto& config : config_files()) designs.push_back(load_hw_config(config));
  for (const HwConfig& hw : designs)
    for (TargetEncoding e : {TargetEncoding::kUnorm8, TargetEncoding::kFloat})
      for (int spp : {4, 16}) {
        const auto [h, frags] = mixed_state_frame(spp, e);
        for (Method m : {Method::kWboit, Method::kSlab, Method::kLkAc, Method::kEndertonAc, Method::kLkDepth,
                         Method::kEndertonDepth, Method::kLkDepthAc, Method::kEndertonDepthAc}) {
          ASSERT_EQ(run_passes(h, m).pass[0], PassKind::kPrepass) << to_string(m);
          const std::string what =
              std::string(to_string(m)) + " " + to_string(e) + " " + std::to_string(spp) + " spp on " + hw.name;
          expect_bit_exact(h, frags, method_config(m, hw.blend.formats), hw, what,
                           m == Method::kLkDepthAc && spp == 4 && e == TargetEncoding::kUnorm8);
        }
      }
}

TEST(BitExactDrawRoutes, OverAPrepassAcAndDepthWriteTheirMarkTargetNotTheColourBuffer) {
  // On the mixed frame (a pre-pass), +ac's stochastic pass moves accum
  // bytes and no colour bytes, +depth's depth-only pass transmittance bytes
  // (its mask), and the report lists the target; on a frame of its src-over
  // draws only (no pre-pass) they write as without draw states: +ac colour,
  // +depth depth only, neither target listed.
  const auto idx = [](Buffer b) { return size_t(b); };
  const auto frame = mixed_state_frame(16, TargetEncoding::kFloat);
  const TraceHeader& h = frame.first;
  const auto& frags = frame.second;
  TraceHeader plain = h;
  std::vector<DrawState> d(h.draws.states().begin(), h.draws.states().end());
  for (DrawState& s : d) {  // every draw src-over
    s = default_draw_state(s.draw_id);
    s.encoding = TargetEncoding::kFloat;
  }
  plain.draws = DrawTable(d);
  for (Method m : {Method::kLkAc, Method::kEndertonAc, Method::kLkDepth, Method::kEndertonDepth}) {
    const bool ac = traits(m).total_alpha;
    const Buffer mark = ac ? Buffer::kAccum : Buffer::kTransmittance;
    for (bool prepass : {true, false}) {
      const TraceHeader& hh = prepass ? h : plain;
      const std::string what = std::string(to_string(m)) + (prepass ? " over a pre-pass" : " without one");
      const CycleRun r = run_cycle([&] { return fragments_from(hh, frags); }, method_config(m), HwConfig{});
      ASSERT_EQ(r.stats.passes.size(), size_t(passes_of(m).count + (prepass ? 1 : 0))) << what;
      const PassStats& st = r.stats.passes[size_t(prepass) + (ac ? 1 : 0)];
      ASSERT_EQ(st.name, "stochastic") << what;
      EXPECT_EQ(r.stats.lists(int(mark)), prepass) << what;
      if (prepass) {
        EXPECT_GT(st.dram.bytes_written[idx(mark)], 0u) << what << ": the stochastic pass's mark";
        EXPECT_EQ(st.dram.bytes_written[idx(Buffer::kColor)], 0u) << what << ": the background's colour kept";
      } else {
        EXPECT_EQ(st.dram.bytes_written[idx(mark)], 0u) << what;
        EXPECT_EQ(st.dram.bytes_written[idx(Buffer::kColor)] > 0, ac) << what;
      }
    }
  }
}

TEST(BitExactDrawRoutes, TheApproximateFidelityCountsWhatTheGoldenModelCounts) {
  // The approximate fidelity runs the same functional stages on the mixed
  // frame: its counters are the golden model's, and its DRAM traffic covers
  // the colour the blended draws read.
  const auto [h, frags] = mixed_state_frame(4, TargetEncoding::kUnorm8);
  const std::string path = ::testing::TempDir() + "/mixed_routes.rtr";
  {
    TraceWriter w(path, h);
    for (const Fragment& f : frags) w.write(f);
    w.finish();
  }
  InputSpec in;
  in.trace_path = path;
  for (Method m :
       {Method::kLk, Method::kWboit, Method::kSlab, Method::kLkAc, Method::kEndertonDepth, Method::kLkDepthAc}) {
    StochasticModel golden(h, method_config(m));
    for (int p = 0; p < golden.passes(); ++p) {
      golden.begin_pass(p);
      for (const Fragment& f : frags) golden.draw(f);
    }
    const ApproxRun a = run_approximate(in, method_config(m), HwConfig{});
    std::vector<uint64_t> want, got;
    golden.counters().for_each([&](const char*, uint64_t v) { want.push_back(v); });
    a.counters.for_each([&](const char*, uint64_t v) { got.push_back(v); });
    EXPECT_EQ(got, want) << to_string(m);
    EXPECT_GT(golden.counters().target_bytes_read, 0u) << "the mixed frame has blended draws";
    EXPECT_GT(golden.kind_fragments()[size_t(DrawKind::kSrcOver)], 0u) << "the mixed frame has src-over draws";
  }
  std::remove(path.c_str());
}

TEST(BitExactTiming, ExtremeTimingParametersNeverChangeTheImage) {
  // One FIFO slot everywhere, one pixel in flight, no overtaking, tiny cache,
  // slow serial sorter, one hash lane, and the opposite extreme.
  const std::vector<std::vector<std::string>> variants = {
      {"source.fifo_depth=1", "distributor.fifo_depth=1", "ordering.fifo_depth=1", "depth_test.fifo_depth=1",
       "tracker.fifo_depth=1", "sorter.fifo_depth=1", "alpha_ref.fifo_depth=1", "ordering.pixels_in_flight=1",
       "ordering.window=1", "depth_test.max_outstanding=1", "cache.size_bytes=1024", "cache.ways=1",
       "sorter.kind=serial", "alpha_ref.lanes=1", "depth_test.samples_per_clock=1", "writeback.samples_per_clock=1",
       "cache.fast_clear=false", "dram.channels=1", "dram.bytes_per_clock=1"},
      {"distributor.rop_units=16", "distributor.tile_pixels=8", "ordering.window=64", "ordering.pixels_in_flight=1024",
       "depth_test.max_outstanding=256", "dram.latency_cycles=2000", "sorter.kind=rank", "alpha_ref.pipeline_depth=32",
       "distributor.interleave=row"},
  };
  for (const auto& v : variants) {
    HwConfig hw;
    std::string what;
    for (const auto& a : v) {
      apply_hw_override(hw, a);
      what += a + " ";
    }
    for (bool lockstep : {false, true}) {
      expect_bit_exact(scene_input("cloth", 8), Method::kLk, hw, what + (lockstep ? "lockstep" : ""), lockstep);
      expect_bit_exact(scene_input("eight-layers", 4), Method::kEnderton, hw, what + (lockstep ? "lockstep" : ""),
                       lockstep);
    }
  }
}

// slab's k and b change its state's size and so its memory traffic: the
// extremes of both, against the golden model, with the narrow and wide designs.
TEST(BitExactTiming, SlabAtEveryLayerAndBitCountExtreme) {
  for (const auto& config : timing_config_files()) {
    const HwConfig hw = load_hw_config(config);
    for (int k : {1, 2, 16})
      for (int b : {1, 4, 64}) {
        GoldenConfig cfg = method_config(Method::kSlab);
        cfg.slab_layers = k;
        cfg.slab_bits = b;
        const std::string what = "slab k " + std::to_string(k) + " b " + std::to_string(b) + " on " + config;
        expect_bit_exact(scene_input("cloth", 4), cfg, hw, what);
        expect_bit_exact(scene_input("smoke", 4), cfg, hw, what);
      }
  }
}

TEST(BitExactTiming, EndertonOriginalSelectionMatchesToo) {
  for (const auto& config : timing_config_files())
    for (Method m : {Method::kEnderton, Method::kEndertonAc, Method::kEndertonDepthAc})
      for (const char* scene : {"cloth", "eight-layers"})
        expect_bit_exact(scene_input(scene, 16), m, load_hw_config(config),
                         std::string(scene) + " " + to_string(m) + " original selection on " + config, false,
                         EndertonSelection::kOriginal);
}

TEST(BitExactTiming, NaiveMethodAndPerSampleDepthTracesRunToo) {
  expect_bit_exact(scene_input("cloth", 4), Method::kNaive, HwConfig{}, "naive cloth 4 spp");
  SceneParams p;
  p.name = "eight-layers";
  p.spp = 8;
  p.depth_mode = DepthMode::kPerSample;
  const std::string path = ::testing::TempDir() + "/cycle_persample.rtr";
  write_scene_trace(p, path);
  InputSpec in;
  in.trace_path = path;
  expect_bit_exact(in, Method::kLk, HwConfig{}, "per-sample depth trace");
}

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

TraceHeader small_header(int spp) {
  TraceHeader h;
  h.width = 64;
  h.height = 64;
  h.spp = spp;
  h.positions = standard_sample_positions(spp);
  return h;
}

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

// ------------------------------------------------------------ config

namespace {
std::string write_tmp(const std::string& name, const std::string& text) {
  const std::string p = ::testing::TempDir() + "/" + name;
  std::ofstream(p) << text;
  return p;
}
void expect_config_error(const std::string& text, const std::string& must_name) {
  const std::string p = write_tmp("bad.toml", text);
  try {
    load_hw_config(p);
    ADD_FAILURE() << "accepted: " << text;
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(must_name), std::string::npos) << e.what() << " should name " << must_name;
    EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << e.what() << " should name the file";
  }
}
}  // namespace

TEST(HwConfigFile, BadKeysAndValuesNameTheKey) {
  expect_config_error("[dram]\nchanel = 2\n", "dram.chanel");
  expect_config_error("[drams]\nchannels = 2\n", "drams");
  expect_config_error("[dram]\nchannels = 0\n", "dram.channels");
  expect_config_error("[dram]\nchannels = \"two\"\n", "dram.channels");
  expect_config_error("[cache]\nline_bytes = 48\n", "cache.line_bytes");
  expect_config_error("[sorter]\nkind = \"quick\"\n", "sorter.kind");
  expect_config_error("[clock]\nfrequency_ghz = -1\n", "clock.frequency_ghz");
  expect_config_error("[cache]\nsize_bytes = 256\nways = 8\n", "cache.size_bytes");
  expect_config_error("[dram\nchannels = 2\n", "bad.toml");
  expect_config_error("[cache]\nfast_clear = 1\n", "cache.fast_clear");
  expect_config_error("[numerics]\nhash_bits = 7\n", "numerics.hash_bits");
  expect_config_error("[numerics]\nalpha_bits = 33\n", "numerics.alpha_bits");
  expect_config_error("[numerics]\nsurface_id_bits = 1.5\n", "numerics.surface_id_bits");
}

TEST(HwConfigFile, CommittedConfigsLoadAndDifferAndDocsListEveryKey) {
  const auto files = config_files();
  ASSERT_GE(files.size(), 3u) << "configs/ needs a default and at least two contrasting designs";
  std::set<std::string> texts;
  for (const auto& f : files) texts.insert(hw_config_to_toml(load_hw_config(f)));
  EXPECT_EQ(texts.size(), files.size()) << "two configs resolve to the same design";
  std::ifstream doc(kSource + "/docs/config.md");
  std::stringstream ss;
  ss << doc.rdbuf();
  for (const auto& p : hw_params())
    EXPECT_NE(ss.str().find("`" + p.key + "`"), std::string::npos) << "docs/config.md does not document " << p.key;
  // The default file is the built-in defaults.
  EXPECT_EQ(hw_config_to_toml(load_hw_config(kSource + "/configs/default.toml")), hw_config_to_toml(HwConfig{}));
}

// The design's digest (default output names) is a fixed function of the
// resolved values: the same on every machine, different for another design.
// FNV-1a 64 of the built-in defaults (a change of any default or key changes it).
constexpr uint64_t kDefaultDesignDigest = 0xa02bd6ce42f7b9c2ull;

TEST(HwConfigFile, DigestIsStableAndSeesEveryKey) {
  EXPECT_EQ(hw_digest_hex(HwConfig{}), hw_digest_hex(load_hw_config(kSource + "/configs/default.toml")));
  EXPECT_EQ(hw_config_digest(HwConfig{}), kDefaultDesignDigest) << "the digest of the defaults changed";
  std::set<std::string> seen{hw_digest_hex(HwConfig{})};
  for (const char* a :
       {"numerics.hash_bits=31", "numerics.alpha_bits=31", "numerics.surface_id_bits=31", "dram.channels=3",
        "sorter.kind=rank", "cache.fast_clear=false", "clock.frequency_ghz=1.25", "blend.accum_format=rgba32f",
        "blend.samples_per_clock=8", "compression.depth=false", "compression.color_k=2", "hiz.enable=false"}) {
    HwConfig hw;
    apply_hw_override(hw, a);
    EXPECT_TRUE(seen.insert(hw_digest_hex(hw)).second) << a << " did not change the digest";
  }
  HwConfig named;
  named.name = "another name";
  EXPECT_EQ(hw_digest_hex(named), hw_digest_hex(HwConfig{})) << "only the values count";
}

TEST(HwConfigFile, OverridesParseStrictly) {
  HwConfig hw;
  apply_hw_override(hw, "dram.channels=3");
  EXPECT_EQ(hw.dram.channels, 3u);
  apply_hw_override(hw, "sorter.kind=rank");
  EXPECT_EQ(hw.sorter.kind, SorterKind::kRank);
  for (const char* bad : {"dram.channels", "dram.channels=x", "dram.channels=3x", "nope.key=1", "cache.fast_clear=yes"})
    EXPECT_THROW(apply_hw_override(hw, bad), ConfigError) << bad;
}

namespace {
std::string config_error(const std::function<void()>& f) {
  try {
    f();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(accepted)";
}
}  // namespace

// An override is parsed and checked first and applied only when valid: a
// rejected one leaves the config as it was, and its error names it, not the
// config it was applied to.
TEST(HwConfigFile, RejectedOverrideNamesItselfAndChangesNothing) {
  HwConfig hw;
  apply_hw_override(hw, "dram.channels=3");
  const std::string before = hw_config_to_toml(hw);
  for (const std::string bad :
       {"cache.ways=65", "cache.ways=0", "cache.ways=-1", "cache.line_bytes=48", "cache.ways=x", "cache.ways= 4",
        "cache.ways=+4", "cache.ways=4 ", "cache.ways=", "cache.ways=99999999999999999999", "clock.frequency_ghz=nan",
        "clock.frequency_ghz=inf", "clock.frequency_ghz=1e999", "clock.frequency_ghz=0x1p0", "clock.frequency_ghz=0",
        "sorter.kind=quick", "cache.fast_clear=1", "cache.wayz=4", "cache.ways"}) {
    const std::string e = config_error([&] { apply_hw_override(hw, bad); });
    EXPECT_EQ(e.rfind("--hw-set " + bad + ": ", 0), 0u) << bad << " -> " << e;
    EXPECT_EQ(e.find("built-in defaults"), std::string::npos) << e;
    EXPECT_EQ(hw_config_to_toml(hw), before) << bad << " changed the config";
    EXPECT_EQ(hw.overrides, std::vector<std::string>{"dram.channels=3"}) << bad;
  }
  // A valid value for the key that breaks the cache shape: accepted on its own
  // (other overrides may follow), rejected by the check after the last one,
  // which names the override, not the defaults it was applied to.
  apply_hw_override(hw, "cache.ways=3");
  const std::string e = config_error([&] { validate_hw_config(hw); });
  EXPECT_EQ(e.rfind("--hw-set cache.ways=3: ", 0), 0u) << e;
  EXPECT_NE(e.find("power-of-two number of sets"), std::string::npos) << e;
  const std::string r = config_error([] { resolve_hw_config("", {"dram.channels=2", "cache.ways=3"}); });
  EXPECT_EQ(r.rfind("--hw-set cache.ways=3: ", 0), 0u) << "names the override that broke it, only that: " << r;
  const std::string two = config_error([] { resolve_hw_config("", {"cache.line_bytes=256", "dram.row_bytes=128"}); });
  EXPECT_EQ(two.rfind("--hw-set cache.line_bytes=256, --hw-set dram.row_bytes=128: dram.row_bytes 128 is smaller", 0),
            0u)
      << two;
}

// The cache shape (and the other cross-key constraints) is checked once,
// after the design file and every override: overrides valid only together
// are accepted in either order.
TEST(HwConfigFile, CacheShapeIsCheckedAfterAllOverrides) {
  // 64-byte lines: 256 bytes hold one 4-way set, not one 8-way set (the default ways).
  for (const auto& sets : std::vector<std::vector<std::string>>{
           {"cache.size_bytes=256", "cache.ways=4"},
           {"cache.ways=4", "cache.size_bytes=256"},
           {"cache.size_bytes=256", "cache.line_bytes=16", "cache.ways=16"},
           {"cache.line_bytes=4096", "dram.row_bytes=4096", "dram.interleave_bytes=4096"}}) {
    HwConfig hw;
    ASSERT_NO_THROW(hw = resolve_hw_config("", sets)) << sets[0] << " then " << sets[1];
    EXPECT_EQ(hw.name, "built-in defaults with --hw-set");
    EXPECT_EQ(hw.overrides, sets);
  }
  const HwConfig hw = resolve_hw_config("", {"cache.size_bytes=256", "cache.ways=4"});
  EXPECT_EQ(hw.cache.ways, 4u);
  EXPECT_EQ(hw.cache.size_bytes, 256u);
  EXPECT_EQ(resolve_hw_config("", {}).name, "built-in defaults");
  // A design file that is only valid with an override: load_hw_config alone
  // rejects it naming the file, resolve_hw_config with the override accepts it.
  const std::string p = write_tmp("small-cache.toml", "[cache]\nsize_bytes = 256\n");
  const std::string alone = config_error([&] { load_hw_config(p); });
  EXPECT_EQ(alone.rfind(p + ": cache.size_bytes 256 is smaller than one set", 0), 0u) << alone;
  EXPECT_EQ(config_error([&] { resolve_hw_config(p, {}); }), alone);
  const HwConfig fixed = resolve_hw_config(p, {"cache.ways=4"});
  EXPECT_EQ(fixed.cache.size_bytes, 256u);
  EXPECT_EQ(fixed.name, p + " with --hw-set");
  // An override that does not touch the broken keys leaves the blame on the file.
  EXPECT_EQ(config_error([&] { resolve_hw_config(p, {"dram.channels=2"}); }).rfind(p + ": ", 0), 0u);
  // A bad override among good ones names itself.
  EXPECT_EQ(config_error([&] {
              resolve_hw_config(p, {"cache.ways=4", "dram.banks=0"});
            }).rfind("--hw-set dram.banks=0: ", 0),
            0u);
}

// The resolved design (the report's hardware.resolved_toml) prints every
// number so that it reads back as the same value: written out and loaded
// again it is the same design, bit for bit.
TEST(HwConfigFile, ResolvedTomlRoundTripsEveryNumber) {
  for (const char* f : {"1.23456789", "0.30000000000000004", "0.3333333333333333", "2", "9.999999999999998", "0.01",
                        "1.5", "6.02214076", "1e-2", "3.0000000000000004"}) {
    HwConfig hw;
    apply_hw_override(hw, std::string("clock.frequency_ghz=") + f);
    apply_hw_override(hw, "cache.size_bytes=1073741824");
    apply_hw_override(hw, "dram.bytes_per_clock=1048575");
    const std::string toml = hw_config_to_toml(hw);
    const HwConfig back = load_hw_config(write_tmp("resolved.toml", toml));
    EXPECT_EQ(std::memcmp(&back.clock.frequency_ghz, &hw.clock.frequency_ghz, sizeof(double)), 0)
        << f << " read back as " << back.clock.frequency_ghz << " from\n"
        << toml;
    EXPECT_EQ(hw_config_to_toml(back), toml) << f;
  }
  HwConfig hw;
  apply_hw_override(hw, "clock.frequency_ghz=1.23456789");
  EXPECT_NE(hw_config_to_toml(hw).find("frequency_ghz = 1.23456789  #"), std::string::npos) << hw_config_to_toml(hw);
  apply_hw_override(hw, "clock.frequency_ghz=2");
  EXPECT_NE(hw_config_to_toml(hw).find("frequency_ghz = 2.0  #"), std::string::npos) << "a TOML float, not an integer";
}

// ------------------------------------------------------------ temporal decoupling

namespace {

CycleRun run_mode(const InputSpec& in, Method m, const HwConfig& hw, bool lockstep) {
  CycleOptions opt;
  opt.lockstep = lockstep;
  return run_cycle(in, method_config(m), hw, opt);
}

/// Every timing figure of two runs, activations aside; fails naming the first
/// that differs.
void expect_same_timing(const CycleStats& a, const CycleStats& b, const std::string& what) {
  ASSERT_EQ(a.total_cycles, b.total_cycles) << what;
  EXPECT_EQ(a.pipeline_cycles, b.pipeline_cycles) << what;
  ASSERT_EQ(a.units.size(), b.units.size()) << what;
  for (size_t i = 0; i < a.units.size(); ++i) {
    const auto &u = a.units[i].stats, &v = b.units[i].stats;
    for (int k = 0; k < kActivities; ++k)
      EXPECT_EQ(u.cycles[size_t(k)], v.cycles[size_t(k)])
          << what << ": " << a.units[i].name << " " << to_string(Activity(k)) << " cycles";
    EXPECT_EQ(u.fragments, v.fragments) << what << ": " << a.units[i].name;
    EXPECT_EQ(u.samples, v.samples) << what << ": " << a.units[i].name;
  }
  ASSERT_EQ(a.fifos.size(), b.fifos.size()) << what;
  for (size_t i = 0; i < a.fifos.size(); ++i) {
    EXPECT_EQ(a.fifos[i].pushes, b.fifos[i].pushes) << what << ": " << a.fifos[i].name;
    EXPECT_EQ(a.fifos[i].max_occupancy, b.fifos[i].max_occupancy) << what << ": " << a.fifos[i].name;
    EXPECT_EQ(a.fifos[i].full_cycles, b.fifos[i].full_cycles) << what << ": " << a.fifos[i].name;
    EXPECT_DOUBLE_EQ(a.fifos[i].mean_occupancy, b.fifos[i].mean_occupancy) << what << ": " << a.fifos[i].name;
  }
  for (size_t i = 0; i < a.caches.size(); ++i)
    for (int k = 0; k < kBuffers; ++k) {
      EXPECT_EQ(a.caches[i].read_hits[size_t(k)], b.caches[i].read_hits[size_t(k)]) << what;
      EXPECT_EQ(a.caches[i].write_hits[size_t(k)], b.caches[i].write_hits[size_t(k)]) << what;
    }
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
        EXPECT_TRUE(dec.image == lock.image) << what;
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

// ------------------------------------------------------------ report fields

namespace {

/// Every leaf field of a report as a path: objects by ".", array elements as
/// "[]". An empty array has no field (e.g. slab's compressed surfaces: none).
void leaf_paths(const nlohmann::ordered_json& j, const std::string& at, std::set<std::string>& out) {
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end(); ++it)
      leaf_paths(it.value(), at.empty() ? it.key() : at + "." + it.key(), out);
  } else if (j.is_array() && j.empty()) {
    return;
  } else if (j.is_array() && j[0].is_object()) {
    for (const auto& e : j) leaf_paths(e, at + "[]", out);
  } else {
    out.insert(at);
  }
}

std::string generated_section(const std::string& doc) {
  const std::string begin = "<!-- report fields: generated by `ropsim report-fields --markdown` -->\n";
  const std::string end = "<!-- end of report fields -->";
  const size_t a = doc.find(begin), b = doc.find(end);
  if (a == std::string::npos || b == std::string::npos || b < a) return "(markers missing)";
  return doc.substr(a + begin.size(), b - a - begin.size());
}

}  // namespace

// Every field of a report is written with its unit and meaning (report_fields.h);
// docs/reports.md is generated from those declarations and must equal them,
// and a real report of every method has no field they do not describe.
TEST(ReportFields, DocsAreGeneratedFromTheDeclarationsAndCoverEveryReport) {
  const auto docs = report_field_docs();
  std::set<std::string> described;
  for (const auto& d : docs) {
    EXPECT_TRUE(described.insert(d.path).second) << d.path << " is described twice";
    EXPECT_FALSE(d.unit.empty()) << d.path << " has no unit";
    EXPECT_FALSE(d.meaning.empty()) << d.path << " has no meaning";
  }
  std::ifstream f(kSource + "/docs/reports.md");
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string want = fields_markdown(docs);
  EXPECT_EQ(generated_section(ss.str()), want)
      << "docs/reports.md is out of date: regenerate its table with `ropsim report-fields --markdown`";

  for (Method m :
       {Method::kLk, Method::kEnderton, Method::kNaive, Method::kA2c, Method::kOpaque, Method::kHashed,
        Method::kHashedA2c, Method::kSlab, Method::kWboit, Method::kLkAc, Method::kEndertonDepth, Method::kLkDepthAc}) {
    InputSpec in = scene_input("smoke", 4);
    ReportContext ctx;
    ctx.input = in;
    ctx.config = method_config(m);
    const CycleRun c = run_cycle(in, ctx.config, HwConfig{});
    std::set<std::string> leaves;
    leaf_paths(cycle_report(ctx, c, std::nullopt), "", leaves);
    for (const auto& p : leaves)
      EXPECT_TRUE(described.count(p)) << to_string(m) << ": report field " << p << " is not described";
    EXPECT_TRUE(leaves.count("timing.units[].cycles.busy")) << "the scan of the report is broken";
  }
}

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
  EXPECT_TRUE(da == lb) << "the decoupled run's waveform differs from the lockstep run's";
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

// ------------------------------------------------------------ sampled simulation (livepoints.h)

namespace {

/// Every pixel the unit's fragments touch holds what `golden` holds (depth
/// and colour bits of every sample, the tracker).
std::string pixels_differ(const SampleStore& unit, const SampleStore& golden, const std::vector<Fragment>& touched) {
  const int spp = unit.header().spp;
  for (const Fragment& f : touched) {
    const uint32_t x = f.x, y = f.y;
    const PixelView a = unit.view(x, y), b = golden.view(x, y);
    const std::string at = "pixel (" + std::to_string(x) + ", " + std::to_string(y) + ")";
    if (!a.depth || !b.depth) return at + ": untouched in " + (a.depth ? "the golden model" : "the unit");
    for (int s = 0; s < spp; ++s)
      if (std::memcmp(&a.depth[s], &b.depth[s], 4) != 0 || std::memcmp(&a.rgb[3 * s], &b.rgb[3 * s], 6) != 0)
        return at + " sample " + std::to_string(s);
    if (a.tracker && !(*a.tracker == *b.tracker)) return at + " tracker";
    if (a.slab && !(*a.slab == *b.slab)) return at + " slab layers";
  }
  return "";
}

/// Every field of two fragments, bit for bit.
bool same_fragment(const Fragment& a, const Fragment& b) {
  auto bits = [](const auto& x, const auto& y) { return std::memcmp(&x, &y, sizeof x) == 0; };
  return a.draw_id == b.draw_id && a.prim_id == b.prim_id && a.x == b.x && a.y == b.y && a.coverage == b.coverage &&
         bits(a.z0, b.z0) && bits(a.dzdx, b.dzdx) && bits(a.dzdy, b.dzdy) && bits(a.z, b.z) && bits(a.rgb, b.rgb) &&
         bits(a.alpha, b.alpha);
}

/// Two libraries hold the same live-points, bit for bit; "" or the first difference.
std::string libraries_differ(const LivePoints& a, const LivePoints& b) {
  if (a.fragments != b.fragments || a.points.size() != b.points.size()) return "sizes";
  if (a.input.digest != b.input.digest || a.input.description != b.input.description) return "input";
  if (!(a.image == b.image)) return "image";
  std::string c;
  std::vector<uint64_t> ca, cb;
  a.counters.for_each([&](const char*, uint64_t v) { ca.push_back(v); });
  b.counters.for_each([&](const char*, uint64_t v) { cb.push_back(v); });
  if (ca != cb) return "counters";
  for (size_t k = 0; k < a.points.size(); ++k) {
    const LivePoint &p = a.points[k], &q = b.points[k];
    const std::string u = "unit " + std::to_string(k) + ": ";
    if (p.first != q.first || p.warmup != q.warmup || p.window != q.window) return u + "placement";
    if (p.fragments.size() != q.fragments.size()) return u + "fragment count";
    for (size_t i = 0; i < p.fragments.size(); ++i)
      if (!same_fragment(p.fragments[i], q.fragments[i])) return u + "fragment " + std::to_string(i);
    auto bits = [](const auto& x, const auto& y) {
      return x.size() == y.size() && (x.empty() || std::memcmp(x.data(), y.data(), x.size() * sizeof x[0]) == 0);
    };
    if (p.pre.tracker != q.pre.tracker || p.pre.slab_bits != q.pre.slab_bits || !bits(p.pre.x, q.pre.x) ||
        !bits(p.pre.y, q.pre.y) || !bits(p.pre.depth, q.pre.depth) || !bits(p.pre.rgb, q.pre.rgb) ||
        !bits(p.pre.planes, q.pre.planes) || p.pre.trackers.size() != q.pre.trackers.size() ||
        p.pre.slabs.size() != q.pre.slabs.size())
      return u + "pre-state";
    for (size_t i = 0; i < p.pre.trackers.size(); ++i)
      if (!(p.pre.trackers[i] == q.pre.trackers[i])) return u + "pre-state tracker";
    for (size_t i = 0; i < p.pre.slabs.size(); ++i)
      if (!(p.pre.slabs[i] == q.pre.slabs[i])) return u + "pre-state slab";
    if (p.resident.size() != q.resident.size()) return u + "resident count";
    for (size_t i = 0; i < p.resident.size(); ++i)
      if (p.resident[i].written != q.resident[i].written || p.resident[i].x != q.resident[i].x ||
          p.resident[i].y != q.resident[i].y || p.resident[i].tracker != q.resident[i].tracker ||
          p.resident[i].layers != q.resident[i].layers)
        return u + "resident " + std::to_string(i);
    if (p.tiles.size() != q.tiles.size()) return u + "tile pixel count";
    for (size_t i = 0; i < p.tiles.size(); ++i)
      if (p.tiles.x[i] != q.tiles.x[i] || p.tiles.y[i] != q.tiles.y[i])
        return u + "tile pixel " + std::to_string(i) + "'s position";
    if (!bits(p.tiles.depth, q.tiles.depth)) return u + "tile pixels' depths";
    if (!bits(p.tiles.rgb, q.tiles.rgb)) return u + "tile pixels' colours";
    if (!bits(p.tiles.planes, q.tiles.planes)) return u + "tile pixels' plane keys";
    if (p.warming.size() != q.warming.size()) return u + "warming count";
    for (size_t i = 0; i < p.warming.size(); ++i)
      if (p.warming[i].covered != q.warming[i].covered || p.warming[i].written != q.warming[i].written ||
          p.warming[i].x != q.warming[i].x || p.warming[i].y != q.warming[i].y ||
          p.warming[i].reached_write != q.warming[i].reached_write || p.warming[i].slab_kept != q.warming[i].slab_kept)
        return u + "warming " + std::to_string(i);
  }
  return "";
}

/// Every figure of two sampled runs, or the first that differs.
std::string runs_differ(const SampledRun& a, const SampledRun& b) {
  auto same = [](const Estimate& x, const Estimate& y) {
    return x.value == y.value && x.low == y.low && x.high == y.high;
  };
  if (!same(a.total_cycles, b.total_cycles)) return "total cycles";
  if (!same(a.dram_bytes_read, b.dram_bytes_read)) return "DRAM bytes read";
  if (!same(a.dram_bytes_written, b.dram_bytes_written)) return "DRAM bytes written";
  if (a.fragments_detailed != b.fragments_detailed) return "fragments detailed";
  if (a.units_estimated.size() != b.units_estimated.size()) return "unit count";
  for (size_t i = 0; i < a.units_estimated.size(); ++i)
    if (a.units_estimated[i].name != b.units_estimated[i].name ||
        a.units_estimated[i].stats.cycles != b.units_estimated[i].stats.cycles)
      return "unit " + a.units_estimated[i].name;
  if (format_bottleneck(a.stats) != format_bottleneck(b.stats)) return "bottleneck";
  if (a.stats.compression_on != b.stats.compression_on) return "compression on";
  bool same_traffic = true;
  auto cmp = [&](const auto& x, const auto& y) { same_traffic = same_traffic && x == y; };
  const CompressionTraffic &ca = a.stats.compression, &cb = b.stats.compression;
  cmp(ca.lines_written, cb.lines_written);
  cmp(ca.lines_read, cb.lines_read);
  cmp(ca.bytes_written, cb.bytes_written);
  cmp(ca.bytes_read, cb.bytes_read);
  cmp(ca.writes_per_class, cb.writes_per_class);
  cmp(ca.metadata_bytes_read, cb.metadata_bytes_read);
  cmp(ca.metadata_bytes_written, cb.metadata_bytes_written);
  cmp(ca.metadata_misses, cb.metadata_misses);
  cmp(ca.hiz_rejected, cb.hiz_rejected);
  if (!same_traffic) return "compression traffic";
  return "";
}

std::string temp_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("ropsim-test-" + std::to_string(::getpid()) + "-" + name)).string();
}

std::string read_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

}  // namespace

// A single unit covering the whole input with no warm-up is the full cycle
// run: the same cycles, DRAM bytes and final state, on every committed
// design (uncompressed.toml too).
TEST(Sampled, OneUnitOverTheWholeInputIsTheFullRun) {
  for (const auto& config : config_files()) {
    const HwConfig hw = load_hw_config(config);
    for (Method m : {Method::kLk, Method::kOpaque}) {
      const InputSpec in = scene_input("cloth", 16);
      SamplingParams p;
      p.units = 1;
      p.unit_fragments = ~uint64_t{0} >> 1;
      p.warmup_fragments = 0;
      const LivePoints lib = record_livepoints(in, method_config(m), p);
      ASSERT_EQ(lib.points.size(), 1u);
      ASSERT_EQ(lib.points[0].fragments.size(), lib.fragments);
      const UnitRun u = simulate_livepoint(lib, 0, hw);
      const CycleRun full = run_cycle(in, method_config(m), hw);
      const std::string what = std::string(to_string(m)) + " on " + config;
      EXPECT_EQ(u.total_cycles, full.stats.total_cycles) << what;
      EXPECT_EQ(u.window_bytes_read + u.tail_bytes_read, full.stats.dram.total_bytes_read()) << what;
      EXPECT_EQ(u.window_bytes_written + u.tail_bytes_written, full.stats.dram.total_bytes_written()) << what;
      if (!hw.compression.any())  // (compressed lines are written in their tile's block size)
        EXPECT_EQ((u.window_lines_dirtied + u.tail_lines_dirtied) * hw.cache.line_bytes,
                  full.stats.dram.total_bytes_written())
            << what << ": every line made dirty is written to DRAM once";
      EXPECT_EQ(first_state_difference(*u.state, *full.state), "") << what;
      EXPECT_TRUE(lib.image == full.image) << what << ": the library holds the golden image";
    }
  }
}

// Each unit, simulated from its live-point, leaves its tiles exactly as the
// golden model has them after the unit's last fragment.
TEST(Sampled, EveryUnitEndsInTheGoldenState) {
  const InputSpec in = scene_input("cloth", 16);
  SamplingParams p;
  p.units = 6;
  p.unit_fragments = 3000;
  p.warmup_fragments = 3000;
  for (Method m : {Method::kLk, Method::kEnderton}) {
    const LivePoints lib = record_livepoints(in, method_config(m), p);
    ASSERT_EQ(lib.points.size(), 6u);
    const FragmentList fl = load_fragments(in);
    for (size_t k = 0; k < lib.points.size(); ++k) {
      const LivePoint& lp = lib.points[k];
      EXPECT_EQ(lp.window, 3000u);
      EXPECT_EQ(lp.fragments.size(),
                lp.warmup + 3000 + (k + 1 < lib.points.size() ? lib.params.cooldown_fragments : 0));
      FunctionalRop golden(fl.header, method_config(m));
      FragWork w;
      for (uint64_t i = 0; i < lp.first + lp.fragments.size(); ++i) {
        w.f = &fl.fragments[i];
        golden.process(w);
      }
      const UnitRun u = simulate_livepoint(lib, k, HwConfig{});
      EXPECT_EQ(pixels_differ(*u.state, golden.store(), lp.fragments), "") << to_string(m) << " unit " << k;
      EXPECT_GT(u.window_cycles, 0u);
    }
    EXPECT_EQ(lib.points.back().first + lib.points.back().fragments.size(), lib.fragments)
        << "the last unit ends the input";
  }
}

// A frame of draw states (opaque, blended and src-over draws) is sampled as
// any other: one unit over it is the full cycle run; each unit ends in the
// golden state; the warming is the fragments' own touches, an opaque or
// blended draw's with its colour read and its depth mask, and no tracker.
TEST(Sampled, AFrameOfOpaqueAndBlendedDrawsIsSampled) {
  const auto [h, frags] = mixed_state_frame(4, TargetEncoding::kUnorm8);
  const std::string path = temp_path("sampled_routes.rtr");
  {
    TraceWriter w(path, h);
    for (const Fragment& f : frags) w.write(f);
    w.finish();
  }
  InputSpec in;
  in.trace_path = path;
  const HwConfig hw;
  for (Method m : {Method::kLk, Method::kOpaque}) {
    const GoldenConfig cfg = method_config(m);
    const std::string what = to_string(m);
    {
      SamplingParams whole;
      whole.units = 1;
      whole.unit_fragments = ~uint64_t{0} >> 1;
      whole.warmup_fragments = 0;
      const LivePoints lib = record_livepoints(in, cfg, whole);
      const UnitRun u = simulate_livepoint(lib, 0, hw);
      const CycleRun full = run_cycle(in, cfg, hw);
      EXPECT_EQ(u.total_cycles, full.stats.total_cycles) << what;
      EXPECT_EQ(u.window_bytes_read + u.tail_bytes_read, full.stats.dram.total_bytes_read()) << what;
      EXPECT_EQ(u.window_bytes_written + u.tail_bytes_written, full.stats.dram.total_bytes_written()) << what;
      EXPECT_EQ(first_state_difference(*u.state, *full.state), "") << what;
    }
    // Every fragment's touch, observed.
    std::vector<Touch> touches(frags.size());
    StochasticModel model(h, cfg, 1);
    model.set_observer([&](size_t i, const FragWork& w) { touches[i] = touch_of(w, false); });
    model.draw_batch(frags.data(), frags.size());
    SamplingParams p;
    p.units = 3;
    p.unit_fragments = 60;
    p.warmup_fragments = 60;
    p.cooldown_fragments = 30;
    p.warming_fragments = 100000;
    const LivePoints lib = record_livepoints(in, cfg, p);
    ASSERT_FALSE(lib.whole) << what;
    ASSERT_EQ(lib.points.size(), 3u) << what;
    for (size_t k = 0; k < lib.points.size(); ++k) {
      const LivePoint& lp = lib.points[k];
      FunctionalRop golden(h, cfg);
      FragWork w;
      for (uint64_t i = 0; i < lp.first + lp.fragments.size(); ++i) {
        w.f = &frags[i];
        golden.process(w);
      }
      const UnitRun u = simulate_livepoint(lib, k, hw);
      EXPECT_EQ(pixels_differ(*u.state, golden.store(), lp.fragments), "") << what << " unit " << k;
      ASSERT_EQ(lp.warming.size(), lp.first) << what;
      for (size_t i = 0; i < lp.warming.size(); ++i) {
        const Touch &a = lp.warming[i], &b = touches[i];
        ASSERT_TRUE(a.covered == b.covered && a.written == b.written && a.reached_write == b.reached_write &&
                    a.routed == b.routed && a.reads_colour == b.reads_colour && a.depth_write == b.depth_write)
            << what << " unit " << k << ": warming touch " << i << " is not fragment " << i << "'s";
      }
    }
    // The lines of the touches: a blended draw that keeps depth reads the
    // colour it writes and writes no depth; no routed touch has a tracker line.
    const AddressMap amap(h.width, h.spp, tracker_state_bytes(h.spp, cfg.numerics.surface_id_bits), hw.cache.line_bytes,
                          FunctionalRop(h, cfg).setup().bytes.stored, 0);
    bool seen = false;
    for (size_t i = 0; i < touches.size(); ++i) {
      const Touch& t = touches[i];
      if (!t.routed) continue;
      EXPECT_EQ(t.depth_write, t.reached_write && draw_writes_depth(h.draws.at(frags[i].draw_id))) << what << " " << i;
      int colour_reads = 0, depth_writes = 0, tracker = 0;
      for_each_touch_line(t, amap, m == Method::kLk, false, [&](uint64_t, bool write, Buffer b) {
        colour_reads += b == Buffer::kColor && !write;
        depth_writes += b == Buffer::kDepth && write;
        tracker += b == Buffer::kTracker;
      });
      EXPECT_EQ(tracker, 0) << what << ": touch " << i << " of an opaque or blended draw has a tracker line";
      if (t.written && t.reads_colour && !t.depth_write) {
        seen = true;
        EXPECT_GT(colour_reads, 0) << what << ": touch " << i;
        EXPECT_EQ(depth_writes, 0) << what << ": touch " << i;
      }
    }
    EXPECT_TRUE(seen) << what << ": the mixed frame has a blended draw that keeps its depth";
  }
  std::remove(path.c_str());
}

// An input whose units would simulate half of it or more in detail is
// simulated whole, as one unit without warm-up: every estimate is the full
// cycle run's figure exactly, with an interval of zero width.
TEST(Sampled, ASmallInputIsSimulatedWholeAndExactly) {
  for (const char* scene : {"testcard", "eight-layers"}) {
    const InputSpec in = scene_input(scene, 16);
    const LivePoints lib = record_livepoints(in, GoldenConfig{}, SamplingParams{});
    ASSERT_TRUE(lib.whole) << scene << ": " << lib.fragments << " fragments";
    ASSERT_EQ(lib.points.size(), 1u);
    for (const auto& config : timing_config_files()) {
      const HwConfig hw = load_hw_config(config);
      const SampledRun s = run_sampled(lib, hw);
      const CycleRun full = run_cycle(in, GoldenConfig{}, hw);
      const std::string what = std::string(scene) + " on " + config;
      EXPECT_EQ(s.total_cycles.value, double(full.stats.total_cycles)) << what;
      EXPECT_EQ(s.dram_bytes_read.value, double(full.stats.dram.total_bytes_read())) << what;
      EXPECT_EQ(s.dram_bytes_written.value, double(full.stats.dram.total_bytes_written())) << what;
      EXPECT_EQ(s.total_cycles.low, s.total_cycles.high) << what;
      EXPECT_EQ(format_bottleneck(s.stats).substr(0, 12), format_bottleneck(full.stats).substr(0, 12)) << what;
    }
  }
  // A large enough input is sampled.
  SamplingParams p;
  p.units = 4;
  p.unit_fragments = 1000;
  p.warmup_fragments = 1000;
  p.cooldown_fragments = 1000;
  EXPECT_FALSE(record_livepoints(scene_input("cloth", 16), GoldenConfig{}, p).whole);
}

// A library written and read back is the library recorded, bit for bit, and
// gives the same estimates; writing it twice gives the same bytes.
TEST(LivePointLibrary, RoundTripIsExactAndDeterministic) {
  const InputSpec in = scene_input("cloth", 16);
  SamplingParams p;
  p.units = 5;
  p.unit_fragments = 1500;
  p.warmup_fragments = 2000;
  p.warming_fragments = 6000;
  for (Method m : {Method::kLk, Method::kSlab, Method::kOpaque}) {
    const LivePoints lib = record_livepoints(in, method_config(m), p, 1);
    EXPECT_EQ(libraries_differ(lib, record_livepoints(in, method_config(m), p, 3)), "")
        << to_string(m) << ": the library recorded on 3 threads differs from 1 thread's";
    const std::string a = temp_path("a.rlp"), b = temp_path("b.rlp");
    write_livepoints(a, lib);
    const LivePoints back = read_livepoints(a);
    EXPECT_EQ(libraries_differ(lib, back), "") << to_string(m);
    write_livepoints(b, back);
    EXPECT_EQ(read_bytes(a), read_bytes(b)) << to_string(m) << ": the same library gives the same bytes";
    EXPECT_EQ(runs_differ(run_sampled(lib, HwConfig{}), run_sampled(back, HwConfig{})), "") << to_string(m);
    std::filesystem::remove(a);
    std::filesystem::remove(b);
  }
}

// A library is written as it is encoded (its size and hash patched into the
// header last); a FIFO, which cannot take them afterwards, gets the payload
// encoded whole first. Both read back as the library.
TEST(LivePointLibrary, AFileAndAFifoBothTakeTheLibrary) {
  SamplingParams p;
  p.units = 3;
  p.unit_fragments = 300;
  const LivePoints lib = record_livepoints(scene_input("testcard", 4), GoldenConfig{}, p);
  const std::string file = temp_path("streamed.rlp"), fifo = temp_path("pipe.rlp"), copy = temp_path("piped.rlp");
  write_livepoints(file, lib);
  EXPECT_EQ(libraries_differ(read_livepoints(file), lib), "") << "the library written to a file";
  std::filesystem::remove(fifo);
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0) << std::strerror(errno);
  std::thread reader([&] {
    std::ifstream in(fifo, std::ios::binary);
    std::ofstream(copy, std::ios::binary) << in.rdbuf();
  });
  write_livepoints(fifo, lib);
  reader.join();
  EXPECT_EQ(libraries_differ(read_livepoints(copy), lib), "") << "the library written through a FIFO";
  for (const std::string& f : {file, fifo, copy}) std::filesystem::remove(f);
}

// A trace whose header records its fragment count gives the same library as
// the same trace without it (counted in a first pass), and a header count
// that disagrees with the records is refused as bad input.
// The recording observes only the T fragments before each live-point (and
// the live-points' own): each live-point's warming must still be exactly the
// touches of the T fragments before it, as one thread drawing the whole input
// with every fragment observed sees them, whether the warmings leave gaps
// between them (small T), overlap the previous live-point (T beyond the
// period) or are empty (T = 0). Its fragments are the input's, with what the
// record does not carry zeroed (a per-sample trace's uncovered depths too).
TEST(LivePointLibrary, TheWarmingIsTheTouchesBeforeEachPoint) {
  SceneParams sp;
  sp.name = "eight-layers";
  sp.spp = 8;
  sp.depth_mode = DepthMode::kPerSample;
  const std::string path = temp_path("warming_persample.rtr");
  write_scene_trace(sp, path);
  InputSpec per_sample;
  per_sample.trace_path = path;
  for (const InputSpec& in : {scene_input("cloth", 16), per_sample}) {
    for (Method m : {Method::kLk, Method::kSlab}) {
      const GoldenConfig cfg = method_config(m);
      // Every fragment's touch, one thread, every fragment observed.
      std::vector<Fragment> all;
      auto src = open_fragments(in);
      const TraceHeader h = src->header();
      for (Fragment f; src->next(f);) all.push_back(f);
      std::vector<Touch> touches(all.size());
      StochasticModel model(h, cfg, 1);
      size_t base = 0;
      model.set_observer([&](size_t i, const FragWork& w) {
        Touch& t = touches[base + i];
        t.x = w.f->x;
        t.y = w.f->y;
        t.covered = w.covered;
        t.reached_write = !w.killed();
        t.written = t.reached_write ? w.written : 0;
        t.slab_kept = t.reached_write && m == Method::kSlab && w.slab.kept;
      });
      for (; base < all.size(); base += 1000) model.draw_batch(&all[base], std::min<size_t>(1000, all.size() - base));
      for (uint64_t T : {uint64_t{0}, uint64_t{700}, uint64_t{9000}, uint64_t{5000000}}) {
        SamplingParams p;
        p.units = 6;
        p.unit_fragments = 400;
        p.warmup_fragments = 600;
        p.cooldown_fragments = 300;
        p.warming_fragments = T;
        const LivePoints lib = record_livepoints(in, cfg, p, 2);
        const std::string what = in.describe() + " " + to_string(m) + " T=" + std::to_string(T) + ": ";
        ASSERT_EQ(lib.fragments, all.size()) << what;
        ASSERT_EQ(lib.points.size(), 6u) << what;
        for (size_t k = 0; k < lib.points.size(); ++k) {
          const LivePoint& lp = lib.points[k];
          const std::string unit = what + "unit " + std::to_string(k) + ": ";
          const uint64_t from = lp.first - std::min<uint64_t>(lp.first, T);
          ASSERT_EQ(lp.warming.size(), lp.first - from) << unit << "the warming holds the T fragments before it";
          for (size_t i = 0; i < lp.warming.size(); ++i) {
            const Touch &a = lp.warming[i], &b = touches[from + i];
            ASSERT_TRUE(a.x == b.x && a.y == b.y && a.covered == b.covered && a.written == b.written &&
                        a.reached_write == b.reached_write && a.slab_kept == b.slab_kept)
                << unit << "warming touch " << i << " is not fragment " << from + i << "'s";
          }
          for (size_t i = 0; i < lp.fragments.size(); ++i) {
            Fragment want = all[lp.first + i];
            const bool per = h.depth_mode == DepthMode::kPerSample;
            for (size_t s = 0; s < want.z.size(); ++s)
              if (!per || s >= size_t(h.spp) || !(want.coverage >> s & 1)) want.z[s] = 0.0f;
            ASSERT_TRUE(same_fragment(lp.fragments[i], want))
                << unit << "fragment " << i << " is not the input's, canonicalised";
          }
        }
      }
    }
  }
  std::filesystem::remove(path);
}

TEST(LivePointLibrary, TheHeaderCountPlacesTheUnitsAsCountingDoes) {
  SceneParams sp;
  sp.name = "smoke";
  sp.spp = 8;
  sp.checksum = false;  // no header check: the count is edited below as an older writer's would read
  const std::string counted = ::testing::TempDir() + "/lp_counted.rtr", plain = ::testing::TempDir() + "/lp_plain.rtr",
                    lying = ::testing::TempDir() + "/lp_lying.rtr";
  write_scene_trace(sp, counted);
  std::string bytes = read_bytes(counted);
  ASSERT_NE(bytes.substr(42, 6), std::string(6, '\0')) << "the writer records the count";
  std::ofstream(plain, std::ios::binary) << bytes.substr(0, 42) + std::string(6, '\0') + bytes.substr(48);
  std::string more = bytes;  // one fragment more than the records
  uint64_t field = 0;
  for (int i = 0; i < 6; ++i) field |= uint64_t(uint8_t(more[size_t(42 + i)])) << (8 * i);
  ++field;
  for (int i = 0; i < 6; ++i) more[size_t(42 + i)] = char(uint8_t(field >> (8 * i)));
  std::ofstream(lying, std::ios::binary) << more;
  SamplingParams p;
  p.units = 4;
  p.unit_fragments = 500;
  p.warmup_fragments = 800;
  InputSpec a, b, c;
  a.trace_path = counted;
  b.trace_path = plain;
  c.trace_path = lying;
  ASSERT_TRUE(open_fragments(a)->fragments_known().has_value());
  ASSERT_FALSE(open_fragments(b)->fragments_known().has_value());
  const LivePoints la = record_livepoints(a, GoldenConfig{}, p);
  LivePoints lb = record_livepoints(b, GoldenConfig{}, p);
  lb.input = la.input;  // the files differ in bytes 42..47 only
  EXPECT_EQ(libraries_differ(la, lb), "");
  try {
    record_livepoints(c, GoldenConfig{}, p);
    ADD_FAILURE() << "a header claiming one fragment more than the trace holds was accepted";
  } catch (const TraceError& e) {
    EXPECT_NE(std::string(e.what()).find("but the header records"), std::string::npos) << e.what();
  }
  for (const std::string& f : {counted, plain, lying}) std::filesystem::remove(f);
}

// One library, read once, serves every design: its estimates equal those of a
// run that records its own live-points for that design.
TEST(LivePointLibrary, ServesEveryDesign) {
  const InputSpec in = scene_input("smoke", 16);
  SamplingParams p;
  p.units = 6;
  p.unit_fragments = 1000;
  p.warmup_fragments = 1500;
  const std::string path = temp_path("designs.rlp");
  write_livepoints(path, record_livepoints(in, GoldenConfig{}, p));
  const LivePoints lib = read_livepoints(path);
  std::filesystem::remove(path);
  for (const auto& config : timing_config_files()) {
    const HwConfig hw = load_hw_config(config);
    const LivePoints own = record_livepoints(in, GoldenConfig{}, p);
    EXPECT_EQ(runs_differ(run_sampled(lib, hw), run_sampled(own, hw)), "") << config;
  }
}

// A library is refused, in one line naming its file, when it is not one, is
// of another version, is truncated or corrupt, or is asked to serve another
// input or method.
TEST(LivePointLibrary, RefusesWhatIsNotItsOwn) {
  const InputSpec in = scene_input("testcard", 4);
  SamplingParams p;
  p.units = 3;
  p.unit_fragments = 200;
  const LivePoints lib = record_livepoints(in, GoldenConfig{}, p);
  const std::string path = temp_path("refuse.rlp"), bad = temp_path("bad.rlp");
  write_livepoints(path, lib);
  const std::string bytes = read_bytes(path);
  auto refused = [&](const std::string& content, const std::string& needle) {
    std::ofstream(bad, std::ios::binary) << content;
    try {
      read_livepoints(bad);
      ADD_FAILURE() << "accepted a library that " << needle;
    } catch (const UserError& e) {
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << "one line: " << e.what();
    }
  };
  refused("", "not a live-point library");
  refused("RTRACE01" + bytes.substr(8), "not a live-point library");
  for (const char version : {char(kLivePointFileVersion - 1), char(kLivePointFileVersion + 1)}) {
    std::string other = bytes;
    other[8] = version;
    refused(other, "version " + std::to_string(int(version)));
  }
  refused(bytes.substr(0, bytes.size() / 2), "truncated");
  std::string flipped = bytes;
  flipped[flipped.size() - 10] = char(flipped[flipped.size() - 10] ^ 0x40);
  refused(flipped, "not a valid live-point library");
  std::string longer = bytes + "x";
  refused(longer, "not a valid live-point library");
  // Another input, another method.
  EXPECT_NO_THROW(check_library_input(lib, path, in));
  EXPECT_THROW(check_library_input(lib, path, scene_input("testcard", 16)), UserError);
  EXPECT_THROW(check_library_input(lib, path, scene_input("cloth", 4)), UserError);
  GoldenConfig other;
  EXPECT_NO_THROW(check_library_method(lib, path, other));
  other.method = Method::kEnderton;
  EXPECT_THROW(check_library_method(lib, path, other), UserError);
  other = GoldenConfig{};
  other.numerics.hash_bits = 16;
  EXPECT_THROW(check_library_method(lib, path, other), UserError);
  std::filesystem::remove(path);
  std::filesystem::remove(bad);
}

namespace {

/// A library's payload (the zstd frame after the 32-byte header), decompressed.
std::string library_payload(const std::string& file) {
  const unsigned long long n = ZSTD_getFrameContentSize(file.data() + 32, file.size() - 32);
  std::string out;
  if (n != ZSTD_CONTENTSIZE_UNKNOWN && n != ZSTD_CONTENTSIZE_ERROR) {
    out.resize(size_t(n));
    const size_t r = ZSTD_decompress(out.data(), out.size(), file.data() + 32, file.size() - 32);
    if (!ZSTD_isError(r)) return out;
  }
  // Streamed: decode piecewise.
  out.clear();
  ZSTD_DCtx* d = ZSTD_createDCtx();
  ZSTD_inBuffer in{file.data() + 32, file.size() - 32, 0};
  std::vector<char> buf(1 << 16);
  while (in.pos < in.size) {
    ZSTD_outBuffer o{buf.data(), buf.size(), 0};
    const size_t r = ZSTD_decompressStream(d, &o, &in);
    EXPECT_FALSE(ZSTD_isError(r)) << ZSTD_getErrorName(r);
    if (ZSTD_isError(r)) break;
    out.append(buf.data(), o.pos);
  }
  ZSTD_freeDCtx(d);
  return out;
}

/// The payload offsets of the fields the forgeries edit, walked from the
/// layout of docs/livepoints.md ("File format").
struct PayloadFields {
  size_t repeat = 0, slab_k = 0, slab_b = 0, unit_fragments = 0, fragments = 0;
  std::vector<std::pair<std::string, size_t>> counters;  ///< name, offset of the value
  size_t image_rows = 0, first_row = 0, row_bytes = 0;
};

PayloadFields walk_payload(const std::string& p) {
  PayloadFields f;
  size_t at = 0;
  auto u64 = [&](size_t o) {
    uint64_t v = 0;
    std::memcpy(&v, p.data() + o, 8);
    return v;
  };
  auto str = [&] { at += 8 + size_t(u64(at)); };
  str();                // trace path
  str();                // scene name
  at += 4 + 4 + 4 + 8;  // spp, width, height, seed
  f.repeat = at;
  at += 4;
  str();        // description
  at += 1 + 8;  // from-trace, digest
  uint32_t width = 0;
  std::memcpy(&width, p.data() + at, 4);
  at += 4 + 4 + 4 + 3 + 12 + 4 + 128;  // the trace header: w, h, spp, modes, clear colour and depth, positions
  str();                               // its scene name
  at += 1;                             // checksummed
  const uint64_t n_draws = u64(at);    // the draw table
  at += 8;
  for (uint64_t i = 0; i < n_draws; ++i) {
    at += 4 + 3 + 9 + 16;  // id, flags, equations, factors, function, mask, encoding, blend colour
    str();                 // its name
  }
  str();                // method name
  at += 4 + 4 + 4 + 8;  // numerics, seed
  f.slab_k = at;
  f.slab_b = at + 4;
  at += 8 + 3;
  f.unit_fragments = at;
  at += 5 * 8 + 8 + 1;  // U, W, C, K, T, R, whole
  f.fragments = at;
  at += 8;
  const uint64_t n_counters = u64(at);
  at += 8;
  for (uint64_t i = 0; i < n_counters; ++i) {
    const size_t len = size_t(u64(at));
    const std::string name = p.substr(at + 8, len);
    at += 8 + len;
    f.counters.emplace_back(name, at);
    at += 8;
  }
  at += 4 + 4 + 12;  // the image: width, height, background
  f.image_rows = at;
  f.first_row = at + 8;
  f.row_bytes = 4 + size_t(width) * 12;
  return f;
}

template <class T>
void poke(std::string& p, size_t at, T v) {
  std::memcpy(p.data() + at, &v, sizeof v);
}

}  // namespace

// The forged payloads kept for the fuzzer (fuzz/regressions/livepoints/,
// made by fuzz/forge_livepoints.py from the documented layout) are of the
// current layout: wrapped with a valid checksum, each is refused for the
// field it forges, and the valid payloads they come from are read.
TEST(LivePointLibrary, TheKeptForgeriesReachTheFieldTheyForge) {
  const std::filesystem::path dir = std::filesystem::path(kSource) / "fuzz" / "regressions" / "livepoints";
  const std::map<std::string, std::string> needle = {
      {"n-2e60", "N 1152921504606846976"},
      {"u-0", "U 0 fragments"},
      {"repeat-0", "repeat 0 is not in [1, 1000]"},
      {"repeat-5000", "repeat 5000 is not in [1, 1000]"},
      {"slab-k-0", "SLAB layers k 0"},
      {"slab-b-100", "SLAB bits b 100"},
      {"counter-0-max", "18446744073709551615"},
      {"counter-1-max", "18446744073709551615"},
      {"pixel-nan", "not a resolved binary16 value"},
      {"pixel-minus-1", "not a resolved binary16 value"},
      {"row-twice", "row"},  // out of order or given twice, or more rows than the image has
      {"k-units-0", "K"}};
  const std::string path = temp_path("kept-forgery.rlp");
  auto read_wrapped = [&](const std::filesystem::path& payload) {
    const std::string bytes = read_bytes(payload.string());
    const std::vector<uint8_t> file =
        wrap_livepoint_payload(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size());
    std::ofstream(path, std::ios::binary)
        .write(reinterpret_cast<const char*>(file.data()), std::streamsize(file.size()));
    read_livepoints(path);
  };
  for (const char* valid : {"lk.payload", "slab.payload"}) EXPECT_NO_THROW(read_wrapped(dir / valid)) << valid;
  size_t checked = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (name.rfind("forged-", 0) != 0) continue;
    std::string field = name.substr(std::string("forged-").size());
    field = field.substr(field.find('-') + 1);  // past the method
    field = field.substr(0, field.size() - std::string(".payload").size());
    const auto it = needle.find(field);
    if (it == needle.end()) continue;  // e.g. pixel-inf: +inf is a value an rgb-f32 trace can resolve to
    ++checked;
    try {
      read_wrapped(e.path());
      ADD_FAILURE() << name << " was accepted";
    } catch (const UserError& err) {
      EXPECT_NE(std::string(err.what()).find(it->second), std::string::npos) << name << ": " << err.what();
    }
  }
  EXPECT_GE(checked, 10u) << "the kept forgeries of docs/livepoints.md's fields";
  std::filesystem::remove(path);
}

// A library whose checksum matches but whose fields lie outside the ranges
// the trace format, the CLI and the recording give is refused, in one line
// naming the file and the field: each forgery edits one field of a valid
// library's payload and wraps it again with a new checksum.
TEST(LivePointLibrary, RefusesEveryOutOfRangeField) {
  SamplingParams p;
  p.units = 3;
  p.unit_fragments = 200;
  p.warmup_fragments = 300;
  p.cooldown_fragments = 100;  // not a whole input: the units are sampled
  InputSpec unorm = scene_input("cloth", 4);
  unorm.scene.color_format = ColorFormat::kRgbUnorm8;  // no colour overflows binary16: +inf cannot be resolved
  GoldenConfig slab;
  slab.method = Method::kSlab;
  const std::string path = temp_path("forged.rlp");
  auto payload_of = [&](const LivePoints& lib) {
    write_livepoints(path, lib);
    return library_payload(read_bytes(path));
  };
  const std::string lk = payload_of(record_livepoints(unorm, GoldenConfig{}, p));
  const std::string sl = payload_of(record_livepoints(scene_input("eight-layers", 4), slab, p));
  auto write_payload = [&](const std::string& payload) {
    const std::vector<uint8_t> file =
        wrap_livepoint_payload(reinterpret_cast<const uint8_t*>(payload.data()), payload.size());
    std::ofstream(path, std::ios::binary)
        .write(reinterpret_cast<const char*>(file.data()), std::streamsize(file.size()));
  };
  for (const std::string* valid : {&lk, &sl}) {  // the walker and the wrapping are right
    write_payload(*valid);
    EXPECT_NO_THROW(read_livepoints(path));
  }
  auto refused = [&](const std::string& what, const std::string& needle) {
    SCOPED_TRACE(what);
    try {
      read_livepoints(path);
      ADD_FAILURE() << "accepted a library with " << what;
    } catch (const UserError& e) {
      const std::string msg = e.what();
      EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << "names the file: " << msg;
      EXPECT_NE(msg.find(needle), std::string::npos) << "names the field (" << needle << "): " << msg;
      EXPECT_EQ(msg.find('\n'), std::string::npos) << "one line: " << msg;
    }
  };
  auto forge = [&](const std::string& base, const std::string& what, const std::string& needle,
                   const std::function<void(std::string&, const PayloadFields&)>& edit) {
    std::string f = base;
    edit(f, walk_payload(base));
    write_payload(f);
    refused(what, needle);
  };
  forge(lk, "N = 2^60", "N 1152921504606846976",
        [](std::string& b, const PayloadFields& at) { poke(b, at.fragments, uint64_t{1} << 60); });
  forge(lk, "U = 0", "U 0 fragments",
        [](std::string& b, const PayloadFields& at) { poke(b, at.unit_fragments, uint64_t{0}); });
  for (uint32_t r : {0u, 5000u})
    forge(lk, "repeat " + std::to_string(r), "repeat " + std::to_string(r) + " is not in [1, 1000]",
          [r](std::string& b, const PayloadFields& at) { poke(b, at.repeat, r); });
  for (float v : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(), -1.0f})
    forge(lk, "a pixel of " + std::to_string(v), "not a resolved binary16 value",
          [v](std::string& b, const PayloadFields& at) { poke(b, at.first_row + 4, v); });
  forge(lk, "a row given twice", "out of order or given twice", [](std::string& b, const PayloadFields& at) {
    uint64_t rows = 0;
    std::memcpy(&rows, b.data() + at.image_rows, 8);
    ASSERT_GE(rows, 1u);
    poke(b, at.image_rows, rows + 1);
    b.insert(at.first_row + at.row_bytes, b.substr(at.first_row, at.row_bytes));
  });
  forge(sl, "SLAB k = 0", "SLAB layers k 0",
        [](std::string& b, const PayloadFields& at) { poke(b, at.slab_k, uint32_t{0}); });
  forge(sl, "SLAB b = 100", "SLAB bits b 100",
        [](std::string& b, const PayloadFields& at) { poke(b, at.slab_b, uint32_t{100}); });
  for (size_t i = 0; i < walk_payload(lk).counters.size(); ++i) {
    const std::string name = walk_payload(lk).counters[i].first;
    forge(lk, name + " = 2^64 - 1", name + " 18446744073709551615",
          [i](std::string& b, const PayloadFields& at) { poke(b, at.counters[i].second, ~uint64_t{0}); });
  }
  // The file header's reserved field (bytes 12..15) is outside the payload.
  write_payload(lk);
  std::string file = read_bytes(path);
  file[13] = 1;
  std::ofstream(path, std::ios::binary) << file;
  refused("a reserved field of 256", "the reserved header field, bytes 12..15, is 256");
  std::filesystem::remove(path);
}

// Units simulated in worker processes give every figure of the run exactly as
// one process does, for any number of workers.
TEST(Sampled, WorkersGiveTheSameFigures) {
  const InputSpec in = scene_input("cloth", 16);
  SamplingParams p;
  p.units = 7;
  p.unit_fragments = 1000;
  p.warmup_fragments = 1000;
  const LivePoints lib = record_livepoints(in, GoldenConfig{}, p);
  for (const char* design : {"uncompressed.toml", "default.toml"}) {  // default: compression and Hi-Z
    const HwConfig hw = load_hw_config(kSource + "/configs/" + design);
    const SampledRun one = run_sampled(lib, hw, 1);
    for (int jobs : {2, 3, 16}) {
      const SampledRun many = run_sampled(lib, hw, jobs);
      EXPECT_EQ(runs_differ(one, many), "") << design << ": " << jobs << " workers";
      EXPECT_EQ(many.jobs, std::min(jobs, 7)) << "no more workers than units";
    }
  }
}

// The bottleneck a sampled run names is the full cycle model's, on each
// design, and its activities add up to the estimated cycles.
TEST(Sampled, BottleneckIsTheCycleModels) {
  const InputSpec in = scene_input("cloth", 16);
  SamplingParams p;
  p.units = 10;
  p.unit_fragments = 1000;
  p.warmup_fragments = 2000;
  const LivePoints lib = record_livepoints(in, GoldenConfig{}, p);
  for (const auto& config : timing_config_files()) {
    const HwConfig hw = load_hw_config(config);
    const SampledRun s = run_sampled(lib, hw);
    const CycleRun full = run_cycle(in, GoldenConfig{}, hw);
    EXPECT_EQ(s.stats.bottleneck.kind, full.stats.bottleneck.kind)
        << config << ": " << format_bottleneck(s.stats) << " vs " << format_bottleneck(full.stats);
    EXPECT_EQ(s.stats.bottleneck.resource, full.stats.bottleneck.resource)
        << config << ": " << format_bottleneck(s.stats) << " vs " << format_bottleneck(full.stats);
    for (const UnitReport& u : s.stats.units) {
      uint64_t sum = 0;
      for (uint64_t c : u.stats.cycles) sum += c;
      // Each activity is rounded on its own: at most one cycle each.
      EXPECT_NEAR(double(sum), double(s.stats.total_cycles), double(kActivities)) << config << " " << u.name;
    }
  }
}

TEST(Sampled, StudentT) {
  EXPECT_NEAR(student_t975(1), 12.706, 1e-9);
  EXPECT_NEAR(student_t975(30), 2.042, 1e-9);
  EXPECT_NEAR(student_t975(40), 2.021, 1e-9);
  EXPECT_NEAR(student_t975(120), 1.980, 1e-9);
  EXPECT_GT(student_t975(50), 2.000);
  EXPECT_LT(student_t975(50), 2.021);
  EXPECT_NEAR(student_t975(1000000), 1.960, 1e-4);
}

// ------------------------------------------------------------ surface compression and Hi-Z

namespace {

/// The default design (compression and Hi-Z, the rasterizer-plane depth encoder).
HwConfig default_design() { return load_hw_config(kSource + "/configs/default.toml"); }

/// A 32 x 32 trace at 16 spp of full-coverage fragments of two "large
/// triangles" (the screen split at x = 20, inside a memory tile): depth
/// planes exact in the bit pattern of binary32 (0.5 + multiples of 2^-18),
/// one colour per primitive. Then, when `layer`, one more full-screen layer
/// in front with opacity alpha and a different colour.
std::string two_planes_trace(const std::string& name, bool layer, float alpha) {
  TraceHeader h = small_header(16);
  h.width = h.height = 32;
  h.color_format = ColorFormat::kRgbUnorm8;
  const std::string path = ::testing::TempDir() + "/" + name + ".rtr";
  TraceWriter w(path, h);
  for (uint32_t y = 0; y < 32; ++y)
    for (uint32_t x = 0; x < 32; ++x) {
      Fragment f;
      f.x = uint16_t(x);
      f.y = uint16_t(y);
      f.coverage = 0xFFFF;
      const bool left = x < 20;
      f.prim_id = left ? 0 : 1;
      f.dzdx = left ? 0x1p-10f : -0x1p-11f;
      f.dzdy = left ? 0x1p-11f : 0x1p-10f;
      f.z0 = (left ? 0.5f + 0x1p-8f : 0.75f) + f.dzdx * (float(x) + 0.5f) + f.dzdy * (float(y) + 0.5f);
      f.rgb = left ? std::array<float, 3>{1.0f, 0.0f, 0.0f} : std::array<float, 3>{0.0f, 1.0f, 0.0f};
      f.alpha = 1.0f;
      w.write(f);
    }
  if (layer)
    for (uint32_t y = 0; y < 32; ++y)
      for (uint32_t x = 0; x < 32; ++x) {
        Fragment f;
        f.x = uint16_t(x);
        f.y = uint16_t(y);
        f.coverage = 0xFFFF;
        f.prim_id = 2;
        f.draw_id = 1;
        f.z0 = 0.5f;
        f.rgb = {0.0f, 0.0f, 1.0f};
        f.alpha = alpha;
        w.write(f);
      }
  w.finish();
  return path;
}

CompressionStats functional_compressibility(const std::string& trace, Method m, const HwConfig& hw) {
  InputSpec in;
  in.trace_path = trace;
  GoldenConfig cfg = method_config(m, hw.blend.formats);
  cfg.compression = hw.compression.setup();
  return run_functional(in, cfg).compression;
}

}  // namespace

TEST(Compression, OpaqueLargeTrianglesCompressToPlanesAndOneColourPerPixel) {
  // 32 x 32 at 16 spp, 16-pixel memory tiles: 64 tiles per surface, U = 1 KiB
  // of depth and 1.5 KiB of colour. A tile inside one triangle needs one
  // plane and no residual (8 + 96 bits); the 8 tiles the edge at x = 20
  // crosses need two planes and a selector bit per sample (8 + 192 + 256
  // bits). Both fit in the quarter block. Colour: one value per pixel,
  // 2 + 48 bits each, 100 bytes a tile: the quarter block (384 B) too.
  const HwConfig hw = default_design();
  const std::string trace = two_planes_trace("opaque-planes", false, 1.0f);
  // The encoder's choice, tile by tile, from the final golden state.
  {
    InputSpec in;
    in.trace_path = trace;
    const FragmentList list = load_fragments(in);
    StochasticModel golden(list.header, method_config(Method::kOpaque));
    for (const auto& f : list.fragments) golden.draw(f);
    uint8_t px[16], py[16];
    for (int s = 0; s < 16; ++s) {
      px[s] = list.header.positions[s].x;
      py[s] = list.header.positions[s].y;
    }
    int one = 0, two = 0;
    for (uint32_t ty = 0; ty < 32; ty += 2)
      for (uint32_t tx = 0; tx < 32; tx += 8) {
        const PixelView v = golden.store().view(tx, ty);
        const DepthFit fit = best_depth_fit(DepthTileIn{v.depth, 16, 16, px, py}, 4);
        ASSERT_TRUE(fit.ok) << "tile at (" << tx << ", " << ty << ")";
        EXPECT_EQ(fit.r, 0) << "exact planes need no residual";
        const bool crossed = tx == 16;
        EXPECT_EQ(fit.planes.size(), crossed ? 2u : 1u) << "tile at (" << tx << ", " << ty << ")";
        EXPECT_EQ(fit.bits, crossed ? 8u + 192u + 256u : 8u + 96u);
        (crossed ? two : one)++;
      }
    EXPECT_EQ(one, 48);
    EXPECT_EQ(two, 16);
  }
  const CompressionStats cs = functional_compressibility(trace, Method::kOpaque, hw);
  const BufferCompression& d = cs.buffers[size_t(Buffer::kDepth)];
  const BufferCompression& c = cs.buffers[size_t(Buffer::kColor)];
  EXPECT_EQ(d.tiles, 64u);
  EXPECT_EQ(d.tiles_cleared, 0u);
  EXPECT_EQ(d.bytes_uncompressed, 64u * 1024);
  EXPECT_EQ(d.bytes_compressed, 64u * 256) << "every depth tile in the quarter block";
  EXPECT_EQ(d.tiles_per_class[2], 64u);
  EXPECT_EQ(d.metadata_bytes, 64u * 2 / 8);
  EXPECT_EQ(c.bytes_uncompressed, 64u * 1536);
  EXPECT_EQ(c.bytes_compressed, 64u * 384) << "one colour per pixel: the quarter block";
  // The cycle model: every line written back moves a quarter of its bytes,
  // and the image and state are the golden model's.
  InputSpec in;
  in.trace_path = trace;
  expect_bit_exact(in, Method::kOpaque, hw, "opaque planes, default design");
  const CycleRun run = run_cycle(in, method_config(Method::kOpaque), hw);
  const CompressionTraffic& t = run.stats.compression;
  for (Buffer b : {Buffer::kDepth, Buffer::kColor}) {
    EXPECT_GT(t.lines_written[size_t(b)], 0u);
    EXPECT_EQ(t.writes_per_class[size_t(b)][2], t.lines_written[size_t(b)]) << to_string(b);
    EXPECT_EQ(t.bytes_written[size_t(b)] * 4, t.bytes_written_uncompressed[size_t(b)]) << to_string(b);
    EXPECT_EQ(run.stats.dram.bytes_written[size_t(b)], t.bytes_written[size_t(b)] + t.metadata_bytes_written[size_t(b)])
        << to_string(b) << ": the surface's DRAM writes are its compressed lines and its state bits";
  }
}

TEST(Compression, AnAlphaOneLayerCompressesLikeOpaqueAndAnLkHalfLayerNeedsTwoColours) {
  const HwConfig hw = default_design();
  const std::string base = two_planes_trace("base", false, 1.0f);
  const std::string full = two_planes_trace("alpha-one", true, 1.0f);
  const std::string half = two_planes_trace("alpha-half", true, 0.5f);
  // alpha = 1: lk writes every covered sample of the front layer, exactly as
  // opaque does: one plane (z = 0.5), one colour per pixel.
  const CompressionStats lk1 = functional_compressibility(full, Method::kLk, hw);
  const CompressionStats op1 = functional_compressibility(full, Method::kOpaque, hw);
  for (Buffer b : {Buffer::kDepth, Buffer::kColor}) {
    EXPECT_EQ(lk1.buffers[size_t(b)].bytes_compressed, op1.buffers[size_t(b)].bytes_compressed) << to_string(b);
    EXPECT_EQ(lk1.buffers[size_t(b)].tiles_per_class, op1.buffers[size_t(b)].tiles_per_class) << to_string(b);
  }
  EXPECT_EQ(op1.buffers[size_t(Buffer::kColor)].bytes_compressed, 64u * 384);
  // alpha = 0.5 over a different colour: lk writes half of the samples
  // (stratified), so every pixel holds two colours: 2 + 96 + 16 x 2 bits a
  // pixel, 260 bytes a tile, still the quarter block but not the one-colour
  // size; the encoded size says so exactly.
  InputSpec in;
  in.trace_path = half;
  const FragmentList list = load_fragments(in);
  StochasticModel golden(list.header, method_config(Method::kLk));
  for (const auto& f : list.fragments) golden.draw(f);
  for (uint32_t ty = 0; ty < 32; ty += 2)
    for (uint32_t tx = 0; tx < 32; tx += 8) {
      const PixelView v = golden.store().view(tx, ty);
      uint32_t max_k = 0;
      const uint64_t bits = color_tile_bits(ColorTileIn{reinterpret_cast<const uint8_t*>(v.rgb), 16, 16}, 4, &max_k);
      EXPECT_EQ(max_k, 2u) << "tile at (" << tx << ", " << ty << ")";
      EXPECT_EQ(bits, 16u * (2 + 96 + 32)) << "every pixel two colours, tile at (" << tx << ", " << ty << ")";
    }
  // With K = 1 the same tiles do not compress at all; opaque's do.
  HwConfig k1 = hw;
  apply_hw_override(k1, "compression.color_k=1");
  EXPECT_EQ(functional_compressibility(half, Method::kLk, k1).buffers[size_t(Buffer::kColor)].tiles_per_class[0], 64u);
  EXPECT_EQ(functional_compressibility(base, Method::kOpaque, k1).buffers[size_t(Buffer::kColor)].tiles_per_class[0],
            0u);
}

namespace {

/// A 64 x 64 opaque height field at 4 spp: a 3 x 3 grid of cells, two
/// triangles each, over the whole screen, vertices jittered and at random
/// depths (seed fixed). Its memory tiles hold 1 to 6 primitives.
std::string height_field_trace(const std::string& name) {
  TraceHeader h = small_header(4);
  const std::string path = ::testing::TempDir() + "/" + name + ".rtr";
  std::mt19937 rng(20261204);
  std::uniform_real_distribution<double> z(0.2, 0.8), jitter(-4.0, 4.0);
  const int cells = 3;
  ScreenVertex v[cells + 1][cells + 1];
  for (int j = 0; j <= cells; ++j)
    for (int i = 0; i <= cells; ++i) {
      const bool edge_x = i == 0 || i == cells, edge_y = j == 0 || j == cells;
      v[j][i].x = 64.0 * i / cells + (edge_x ? 0.0 : jitter(rng));
      v[j][i].y = 64.0 * j / cells + (edge_y ? 0.0 : jitter(rng));
      v[j][i].z = z(rng);
    }
  TraceWriter w(path, h);
  Rasterizer r(h);
  uint32_t prim = 0;
  for (int j = 0; j < cells; ++j)
    for (int i = 0; i < cells; ++i)
      for (int half = 0; half < 2; ++half) {
        ScreenTriangle t;
        t.prim_id = prim++;
        t.v = half ? std::array<ScreenVertex, 3>{v[j][i], v[j + 1][i + 1], v[j][i + 1]}
                   : std::array<ScreenVertex, 3>{v[j][i], v[j + 1][i], v[j + 1][i + 1]};
        r.rasterize(t, [&](const Fragment& f) { w.write(f); });  // either winding (no culling)
      }
  w.finish();
  return path;
}

}  // namespace

TEST(Compression, ThePlaneEncoderStoresATileInThePlanesOfThePrimitivesItHolds) {
  // The rasterizer-plane encoder's bytes, computed here from the format
  // alone: replay the trace's depth test, keep each sample's last writer,
  // count each memory tile's distinct primitives p (a cleared sample adds
  // the clear plane), and size the tile as 8 + 96 p + n ceil(log2 p) bits in
  // the smallest block of U, U/2, U/4, U/8 that holds it (uncompressed past
  // U/2 or P = 4 planes). At 4 spp (U = 256 B, n = 64) one plane takes 13 B
  // (U/8), two 33 B and three 53 B (U/4), four 65 B (U/2), five or more U.
  HwConfig hw = default_design();
  apply_hw_override(hw, "compression.size_classes=4");
  apply_hw_override(hw, "cache.size_bytes=1048576");  // every line written back once, at the end
  ASSERT_EQ(hw.compression.depth_encoder, DepthEncoder::kPlane) << "the default encoder";
  const std::string trace = height_field_trace("height-field");
  InputSpec in;
  in.trace_path = trace;
  const FragmentList list = load_fragments(in);
  const TraceHeader& h = list.header;
  std::vector<float> depth(64 * 64 * 4, canonical_depth(h.clear_depth));
  std::vector<int64_t> writer(depth.size(), -1);
  for (const Fragment& f : list.fragments) {
    float z[64];
    fragment_sample_depths(h, f, z);
    for (uint64_t m = f.coverage; m; m &= m - 1) {
      const int s = __builtin_ctzll(m);
      const size_t i = (size_t(f.y) * 64 + f.x) * 4 + size_t(s);
      if (z[s] <= depth[i]) {  // the opaque method's depth test (LESS_EQUAL)
        depth[i] = z[s];
        writer[i] = int64_t(f.prim_id);
      }
    }
  }
  uint64_t expected = 0;
  std::array<uint64_t, 4> per_class{};
  std::map<size_t, int> tiles_by_planes;
  for (uint32_t ty = 0; ty < 64; ty += 8)
    for (uint32_t tx = 0; tx < 64; tx += 8)
      for (uint32_t rows = 0; rows < 8; rows += 2) {  // a memory tile: two rows of the 8 x 8 tile
        std::set<int64_t> planes;
        for (uint32_t y = ty + rows; y < ty + rows + 2; ++y)
          for (uint32_t x = tx; x < tx + 8; ++x)
            for (size_t s = 0; s < 4; ++s) planes.insert(writer[(size_t(y) * 64 + x) * 4 + s]);
        const size_t p = planes.size();
        ++tiles_by_planes[p];
        const uint64_t bits = 8 + 96 * p + 64 * uint64_t(p > 1 ? (p > 2 ? (p > 4 ? 3 : 2) : 1) : 0);
        const uint64_t bytes = (bits + 7) / 8;
        int c = 0;
        if (p <= 4)
          for (int j = 1; j < 4; ++j)
            if (bytes <= (256u >> j)) c = j;
        ++per_class[size_t(c)];
        expected += 256u >> c;
      }
  ASSERT_GE(tiles_by_planes.size(), 4u) << "the mesh must give tiles of several plane counts";
  ASSERT_GT(tiles_by_planes.rbegin()->first, 4u) << "and some tile past P planes";
  const CompressionStats cs = functional_compressibility(trace, Method::kOpaque, hw);
  const BufferCompression& d = cs.buffers[size_t(Buffer::kDepth)];
  EXPECT_EQ(d.tiles, 256u);
  EXPECT_EQ(d.tiles_cleared, 0u) << "the mesh covers the screen";
  EXPECT_EQ(d.bytes_uncompressed, 256u * 256);
  EXPECT_EQ(d.bytes_compressed, expected) << "the functional measure";
  EXPECT_EQ(d.tiles_per_class, per_class);
  // The cycle model writes each depth line back once, at the end: its lines
  // move line_bytes >> class of their tile, so its bytes are the same sum.
  expect_bit_exact(in, method_config(Method::kOpaque), hw, "height field, plane encoder");
  const CycleRun run = run_cycle(in, method_config(Method::kOpaque), hw);
  EXPECT_EQ(run.stats.compression.bytes_written[size_t(Buffer::kDepth)], expected) << "the cycle model's writebacks";
  // The fit encoder finds its planes in the stored depths, with residuals
  // where a primitive's depths are not linear in their bit patterns: on
  // this mesh it needs more bytes, and the images are the same.
  HwConfig fit = hw;
  apply_hw_override(fit, "compression.depth_encoder=fit");
  const CompressionStats fit_stats = functional_compressibility(trace, Method::kOpaque, fit);
  const BufferCompression& f = fit_stats.buffers[size_t(Buffer::kDepth)];
  EXPECT_GT(f.bytes_compressed, d.bytes_compressed) << "the fit on a mesh of random slopes";
  expect_bit_exact(in, method_config(Method::kOpaque), fit, "height field, fit encoder");
}

TEST(HiZ, RejectsFragmentsBehindAFinishedOpaqueTileWithoutReadingDepthAndNeverOneThatPasses) {
  // The two opaque planes (depths in [0.5, 0.81)), written back by a small
  // cache, then a full-screen layer behind everything (z = 0.9): Hi-Z
  // rejects it in every tile whose bound was written back, reading no depth;
  // a layer in front (z = 0.25) is never rejected. The state is the golden
  // model's either way (an internal error stops the run if Hi-Z ever
  // rejected a fragment with a surviving sample).
  HwConfig hw = default_design();
  apply_hw_override(hw, "compression.depth=false");  // Hi-Z alone: the bound from the written-back tile
  apply_hw_override(hw, "cache.size_bytes=4096");
  for (float z : {0.9f, 0.25f}) {
    TraceHeader h = small_header(16);
    h.width = h.height = 32;
    const std::string path = ::testing::TempDir() + "/hiz-" + std::to_string(z) + ".rtr";
    {
      TraceWriter w(path, h);
      InputSpec base;
      base.trace_path = two_planes_trace("hiz-base", false, 1.0f);
      for (const auto& f : load_fragments(base).fragments) w.write(f);
      for (int pass = 0; pass < 2; ++pass)  // the second pass: the bounds are written back by then
        for (uint32_t y = 0; y < 32; ++y)
          for (uint32_t x = 0; x < 32; ++x) {
            Fragment f;
            f.x = uint16_t(x);
            f.y = uint16_t(y);
            f.coverage = 0xFFFF;
            f.prim_id = 9;
            f.z0 = z;
            f.rgb = {0.0f, 0.0f, 1.0f};
            f.alpha = 1.0f;
            w.write(f);
          }
      w.finish();
    }
    InputSpec in;
    in.trace_path = path;
    expect_bit_exact(in, Method::kOpaque, hw, "Hi-Z, layer at " + std::to_string(z));
    const CycleRun run = run_cycle(in, method_config(Method::kOpaque), hw);
    const CompressionTraffic& t = run.stats.compression;
    EXPECT_EQ(t.hiz_tests, 3u * 32 * 32);
    if (z > 0.85f) {
      EXPECT_GT(t.hiz_rejected, 0u) << "a layer behind finished tiles";
      EXPECT_LE(t.hiz_rejected, 2u * 32 * 32);
      EXPECT_EQ(t.hiz_lines_skipped, t.hiz_rejected) << "a rejected fragment reads none of its depth (one line)";
      HwConfig off = hw;
      apply_hw_override(off, "hiz.enable=false");
      const CycleRun base_run = run_cycle(in, method_config(Method::kOpaque), off);
      CacheStats with, without;
      for (const auto& c : run.stats.caches) with += c;
      for (const auto& c : base_run.stats.caches) without += c;
      const uint64_t reads = with.read_hits[0] + with.read_misses[0],
                     reads_off = without.read_hits[0] + without.read_misses[0];
      EXPECT_EQ(reads_off - reads, t.hiz_lines_skipped) << "the depth reads Hi-Z saved";
    } else {
      EXPECT_EQ(t.hiz_rejected, 0u) << "a layer in front of everything passes";
    }
  }
}

TEST(BitExactCompression, TheUncompressedBaselineAndTheFitEncoderMatchTheGoldenModel) {
  // The bit-exact matrix (BitExact) runs the committed designs, which
  // compress; compression is timing only, so the same methods match the
  // golden model with it off too (configs/uncompressed.toml: two scenes at 4
  // and 16 spp), with the fit depth encoder, and on a small cache (evictions
  // and fills of compressed lines) -- ten methods each, a smaller matrix
  // than BitExact's (CI budget).
  const HwConfig off = load_hw_config(kSource + "/configs/uncompressed.toml");
  ASSERT_FALSE(off.compression.any() || off.hiz.enable) << "uncompressed.toml compresses";
  HwConfig small = default_design();
  apply_hw_override(small, "cache.size_bytes=4096");
  HwConfig fit = small;
  apply_hw_override(fit, "compression.depth_encoder=fit");
  struct Case {
    const HwConfig* hw;
    const char* scene;
    int spp;
  };
  for (const Case& c : {Case{&off, "eight-layers", 4}, Case{&off, "eight-layers", 16}, Case{&off, "opaque", 4},
                        Case{&off, "opaque", 16}, Case{&small, "cloth", 4}, Case{&fit, "cloth", 4}})
    for (Method m : {Method::kOpaque, Method::kA2c, Method::kEnderton, Method::kLk, Method::kHashed, Method::kHashedA2c,
                     Method::kSlab, Method::kWboit, Method::kLkDepthAc, Method::kEndertonAc})
      expect_bit_exact(
          scene_input(c.scene, c.spp), m, *c.hw,
          std::string(c.scene) + " " + std::to_string(c.spp) + " spp " + to_string(m) + " on " + c.hw->name +
              " cache " + std::to_string(c.hw->cache.size_bytes) +
              (c.hw->compression.depth ? std::string(" ") + to_string(c.hw->compression.depth_encoder) + " encoder"
                                       : std::string(" uncompressed")));
}

namespace {

/// The first difference between two warmed compression states, or "".
std::string warm_states_differ(const CompressionModel::WarmState& a, const CompressionModel::WarmState& b) {
  for (size_t s = 0; s < size_t(kBuffers); ++s) {
    if (a.stored[s].size() != b.stored[s].size()) return "surface " + std::to_string(s) + "'s tile count";
    for (size_t t = 0; t < a.stored[s].size(); ++t)
      if (a.stored[s][t] != b.stored[s][t])
        return "surface " + std::to_string(s) + " tile " + std::to_string(t) + "'s state bits " +
               std::to_string(a.stored[s][t]) + " vs " + std::to_string(b.stored[s][t]);
  }
  if (a.zmax.size() != b.zmax.size()) return "Hi-Z tile count";
  for (size_t t = 0; t < a.zmax.size(); ++t)
    if (std::memcmp(&a.zmax[t], &b.zmax[t], sizeof(float)) != 0)
      return "Hi-Z tile " + std::to_string(t) + ": " + std::to_string(a.zmax[t]) + " vs " + std::to_string(b.zmax[t]);
  if (a.meta_tags.size() != b.meta_tags.size()) return "metadata cache count";
  for (size_t r = 0; r < a.meta_tags.size(); ++r)
    for (size_t w = 0; w < a.meta_tags[r].size(); ++w) {
      if (a.meta_tags[r][w] != b.meta_tags[r][w])
        return "ROP " + std::to_string(r) + " metadata way " + std::to_string(w);
      if (a.meta_dirty[r][w] != b.meta_dirty[r][w])
        return "ROP " + std::to_string(r) + " metadata way " + std::to_string(w) + "'s dirty bit";
    }
  return "";
}

}  // namespace

// The default design (compression and Hi-Z) is sampled: on the
// cloth at 16 spp (lk, 6 units of 1,500 fragments, 2,000 of warm-up, the
// recording's seed fixed by the method's default), the 95 % intervals of
// total cycles, DRAM bytes read and DRAM bytes written cover the full cycle
// model's, and the estimates are within 20 % of them (this small input's
// own sampling error: without compression, on the default design, the same
// sampling reads 10 % more than the cycle model); the estimate reports
// compressed traffic and Hi-Z tests. Deterministic: the bounds hold or fail
// every run.
TEST(CompressionFidelities, SampledIntervalsCoverTheCycleModelWithCompressionAndHiZ) {
  const HwConfig hw = default_design();
  const InputSpec in = scene_input("cloth", 16);
  SamplingParams p;
  p.units = 6;
  p.unit_fragments = 1500;
  p.warmup_fragments = 2000;
  p.cooldown_fragments = 1000;
  const LivePoints lib = record_livepoints(in, method_config(Method::kLk), p, 1);
  ASSERT_FALSE(lib.whole) << "the test must sample: the cloth has " << lib.fragments << " fragments";
  const SampledRun s = run_sampled(lib, hw, 1);
  const CycleRun full = run_cycle(in, method_config(Method::kLk), hw);
  ASSERT_TRUE(full.stats.compression_on);
  const struct {
    const char* what;
    Estimate e;
    double truth;
  } figs[] = {{"total cycles", s.total_cycles, double(full.stats.total_cycles)},
              {"DRAM bytes read", s.dram_bytes_read, double(full.stats.dram.total_bytes_read())},
              {"DRAM bytes written", s.dram_bytes_written, double(full.stats.dram.total_bytes_written())}};
  for (const auto& f : figs) {
    EXPECT_TRUE(f.e.low <= f.truth && f.truth <= f.e.high)
        << f.what << ": the 95 % interval [" << f.e.low << ", " << f.e.high << "] (estimate " << f.e.value
        << ") does not cover the cycle model's " << f.truth;
    EXPECT_LE(std::abs(f.e.value / f.truth - 1.0), 0.20)
        << f.what << ": the estimate " << f.e.value << " is more than 20 % from the cycle model's " << f.truth;
  }
  ASSERT_TRUE(s.stats.compression_on) << "the estimate reports the compression traffic";
  const CompressionTraffic& c = s.stats.compression;
  const size_t d = size_t(Buffer::kDepth);
  EXPECT_GT(c.hiz_tests, 0u) << "Hi-Z statistics are estimated";
  EXPECT_GT(c.bytes_written_uncompressed[d], c.bytes_written[d])
      << "the depth written is estimated compressed (" << c.bytes_written[d] << " of "
      << c.bytes_written_uncompressed[d] << " bytes)";
  EXPECT_GT(c.metadata_bytes_read[d] + c.metadata_bytes_written[d], 0u) << "metadata bytes are estimated";
  const double hiz_truth = double(full.stats.compression.hiz_rejected);
  EXPECT_LE(std::abs(double(c.hiz_rejected) - hiz_truth), 0.25 * hiz_truth + 100)
      << "Hi-Z rejections: sampled " << c.hiz_rejected << ", cycle " << full.stats.compression.hiz_rejected;
  // Without the warmed compression state (a unit starting with every tile
  // never written back and an empty Hi-Z) the unit would read depth
  // uncompressed: the warming must have set state bits.
  const UnitRun u = simulate_livepoint(lib, 2, hw);
  size_t set = 0;
  for (uint8_t st : u.warmed.stored[d]) set += st != 0xFF;
  EXPECT_GT(set, 0u) << "the warming set no tile's state bits";
}

TEST(CompressionFidelities, TheLibraryHoldsThePlaneKeysTheEncoderSizesTilesBy) {
  // The rasterizer-plane encoder sizes a tile by the primitives that wrote its
  // depths, so a live-point holds each pre-state and tile sample's plane
  // key: the clear key exactly where the depth is still the clear depth (the
  // cloth never writes depth 1), a primitive's key elsewhere. The warmed
  // state reads them: with every key made one primitive's, every written
  // tile is one plane and the unit warms other state bits.
  SamplingParams p;
  p.units = 3;
  p.unit_fragments = 1500;
  p.warmup_fragments = 2000;
  const InputSpec in = scene_input("cloth", 16);
  const LivePoints lib = record_livepoints(in, method_config(Method::kLk), p, 1);
  const float clear = canonical_depth(lib.header.clear_depth);
  size_t keyed = 0;
  for (const LivePoint& lp : lib.points)
    for (const auto* px : {&lp.pre.depth, &lp.tiles.depth}) {
      const std::vector<uint64_t>& keys = px == &lp.pre.depth ? lp.pre.planes : lp.tiles.planes;
      ASSERT_EQ(keys.size(), px->size()) << "a plane key for every sample";
      for (size_t i = 0; i < px->size(); ++i) {
        const bool cleared = depth_bits((*px)[i]) == depth_bits(clear);
        ASSERT_EQ(keys[i] == kClearPlaneKey, cleared) << "sample " << i << " depth " << (*px)[i];
        keyed += !cleared;
      }
    }
  ASSERT_GT(keyed, 0u) << "the live-points hold written samples";
  const HwConfig hw = default_design();
  ASSERT_TRUE(hw.compression.setup().plane_keys());
  const std::string path = temp_path("one-plane.rlp");
  write_livepoints(path, lib);
  LivePoints one = read_livepoints(path);
  std::filesystem::remove(path);
  for (LivePoint& lp : one.points)
    for (auto* keys : {&lp.pre.planes, &lp.tiles.planes})
      for (uint64_t& k : *keys)
        if (k != kClearPlaneKey) k = plane_key(0, 0);
  bool differs = false;
  for (size_t k = 0; k < lib.points.size(); ++k)
    differs |= warm_states_differ(simulate_livepoint(lib, k, hw).warmed, simulate_livepoint(one, k, hw).warmed) != "";
  EXPECT_TRUE(differs) << "the warmed compression state does not depend on the plane keys";
}

// The warming takes every written memory tile of a unit's tiles as written
// back, so the metadata cache of the ROP that owns it has held its state bits,
// as a full run's has: after the warming each such tile's state bits are in
// that cache, dirty, however few fragments' touches warmed it (here 64, which
// reach few of the units' tiles). Without them a unit's window misses in the
// metadata caches where the full run's same window hits.
TEST(CompressionFidelities, TheWarmedMetadataCachesHoldTheUnitsWrittenTiles) {
  const HwConfig hw = default_design();
  SamplingParams p;
  p.units = 3;
  p.unit_fragments = 1500;
  p.warmup_fragments = 2000;
  p.warming_fragments = 64;
  const LivePoints lib = record_livepoints(scene_input("cloth", 16), method_config(Method::kLk), p, 1);
  ASSERT_FALSE(lib.whole);
  const uint32_t tp = hw.compression.tile_pixels, per = 64 / tp;
  const uint64_t tiles_x = ceil_div(lib.header.width, 8u), line_mask = ~(uint64_t{hw.cache.line_bytes} - 1);
  const int bits = metadata_bits(hw.compression.setup().format);
  const RopOwnership owner(hw.distributor, lib.header.width);
  size_t checked = 0;
  for (size_t k = 0; k < lib.points.size(); ++k) {
    const UnitRun u = simulate_livepoint(lib, k, hw);
    for (Buffer b : {Buffer::kDepth, Buffer::kColor}) {
      const std::vector<uint8_t>& stored = u.warmed.stored[size_t(b)];
      for (uint64_t m = 0; m < stored.size(); ++m) {
        if (stored[m] == 0xFF) continue;  // not written back
        const uint64_t t = m / per;
        const uint32_t first = uint32_t(m % per) * tp;
        const uint32_t x = uint32_t(t % tiles_x) * 8 + first % 8, y = uint32_t(t / tiles_x) * 8 + first / 8;
        const uint32_t rop = owner.rop_of(x, y);
        const uint64_t line = ((uint64_t(b) << 48 | uint64_t{1} << 47) + m * uint64_t(bits) / 8) & line_mask;
        const std::vector<uint64_t>& tags = u.warmed.meta_tags[rop];
        const auto it = std::find(tags.begin(), tags.end(), line);
        ASSERT_NE(it, tags.end()) << "unit " << k << ": surface " << int(b) << " tile " << m
                                  << "'s state bits are not in ROP " << rop << "'s metadata cache";
        EXPECT_TRUE(u.warmed.meta_dirty[rop][size_t(it - tags.begin())])
            << "unit " << k << ": surface " << int(b) << " tile " << m << "'s state bits are not dirty";
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 0u) << "the units have written tiles";
}

// With compression and Hi-Z too, an input simulated whole as one unit is
// the full cycle run: the same cycles, DRAM bytes and compression traffic.
TEST(CompressionFidelities, AWholeInputSampledIsTheFullRun) {
  const HwConfig hw = default_design();
  const InputSpec in = scene_input("cloth", 16);
  SamplingParams p;
  p.units = 1;
  p.unit_fragments = ~uint64_t{0} >> 1;
  p.warmup_fragments = 0;
  const LivePoints lib = record_livepoints(in, method_config(Method::kLk), p, 1);
  ASSERT_TRUE(lib.whole);
  const SampledRun s = run_sampled(lib, hw, 1);
  const CycleRun full = run_cycle(in, method_config(Method::kLk), hw);
  EXPECT_EQ(s.total_cycles.value, double(full.stats.total_cycles));
  EXPECT_EQ(s.dram_bytes_read.value, double(full.stats.dram.total_bytes_read()));
  EXPECT_EQ(s.dram_bytes_written.value, double(full.stats.dram.total_bytes_written()));
  const CompressionTraffic &a = s.stats.compression, &b = full.stats.compression;
  for (size_t i = 0; i < size_t(kBuffers); ++i) {
    EXPECT_EQ(a.bytes_written[i], b.bytes_written[i]) << "surface " << i;
    EXPECT_EQ(a.bytes_read[i], b.bytes_read[i]) << "surface " << i;
    EXPECT_EQ(a.metadata_bytes_read[i], b.metadata_bytes_read[i]) << "surface " << i;
    EXPECT_EQ(a.metadata_bytes_written[i], b.metadata_bytes_written[i]) << "surface " << i;
  }
  EXPECT_EQ(a.hiz_tests, b.hiz_tests);
  EXPECT_EQ(a.hiz_rejected, b.hiz_rejected);
}

// A corrupted tile-pixel record (docs/livepoints.md, "File format") is
// refused in one line naming the file, the live-point's record and what is
// wrong: a depth out of [0, 1], a pixel the pre-state holds, one out of
// order, one that is not a resident pixel.
TEST(LivePointLibrary, RefusesACorruptTilePixelRecord) {
  SamplingParams p;
  p.units = 3;
  p.unit_fragments = 1500;
  p.warmup_fragments = 2000;
  const LivePoints lib = record_livepoints(scene_input("cloth", 16), method_config(Method::kLk), p, 1);
  size_t k = 0;
  while (k < lib.points.size() && lib.points[k].tiles.size() < 2) ++k;
  ASSERT_LT(k, lib.points.size()) << "a live-point with two tile pixels to corrupt";
  const std::string path = temp_path("corrupt-tiles.rlp");
  const std::string record = "live-point " + std::to_string(k) + "'s tile pixels";
  auto refused = [&](const std::string& what, const std::function<void(LivePoint&)>& edit, const std::string& needle) {
    SCOPED_TRACE(what);
    LivePoints forged = read_livepoints((write_livepoints(path, lib), path));
    edit(forged.points[k]);
    write_livepoints(path, forged);
    try {
      read_livepoints(path);
      ADD_FAILURE() << "accepted a library with " << what;
    } catch (const UserError& e) {
      const std::string msg = e.what();
      EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << "names the file: " << msg;
      EXPECT_NE(msg.find(record), std::string::npos) << "names the record (" << record << "): " << msg;
      EXPECT_NE(msg.find(needle), std::string::npos) << "says what is wrong (" << needle << "): " << msg;
      EXPECT_EQ(msg.find('\n'), std::string::npos) << "one line: " << msg;
    }
  };
  refused(
      "a depth of 2", [](LivePoint& lp) { lp.tiles.depth[0] = 2.0f; }, "a tile pixel's depth is not in [0, 1]");
  refused(
      "a pre-state pixel",
      [](LivePoint& lp) {
        // The record reduced to one pixel: one the pre-state holds with written samples.
        for (const Resident& r : lp.resident)
          if (r.written)
            for (size_t i = 0; i < lp.pre.size(); ++i)
              if (lp.pre.x[i] == r.x && lp.pre.y[i] == r.y) {
                const size_t spp = lp.tiles.depth.size() / lp.tiles.size();
                lp.tiles.x.assign(1, r.x);
                lp.tiles.y.assign(1, r.y);
                lp.tiles.depth.resize(spp);
                lp.tiles.rgb.resize(3 * spp);
                lp.tiles.planes.resize(spp);
                return;
              }
        ADD_FAILURE() << "no pre-state pixel with written samples";
      },
      "is a pre-state pixel too");
  refused(
      "two pixels swapped",
      [](LivePoint& lp) {
        std::swap(lp.tiles.x[0], lp.tiles.x[1]);
        std::swap(lp.tiles.y[0], lp.tiles.y[1]);
      },
      "out of (y, x) order");
  refused(
      "a pixel that is not resident", [&](LivePoint& lp) { lp.resident.clear(); },
      "more tile pixels than the live-point's resident pixels");
  std::filesystem::remove(path);
}

// The library carries the tiles' contents exactly: written, read back and
// compared field by field (the first difference named), and the compression
// state a design warms from it (state bits, Hi-Z bounds, metadata caches) is
// the same from the recorded library and from the one read back.
TEST(LivePointLibrary, TheTilesRoundTripAndWarmTheSameCompressionState) {
  const HwConfig hw = default_design();
  const InputSpec in = scene_input("cloth", 16);
  SamplingParams p;
  p.units = 4;
  p.unit_fragments = 1500;
  p.warmup_fragments = 2000;
  p.warming_fragments = 8000;
  const LivePoints lib = record_livepoints(in, method_config(Method::kLk), p, 1);
  size_t tile_pixels = 0;
  for (const LivePoint& lp : lib.points) tile_pixels += lp.tiles.size();
  ASSERT_GT(tile_pixels, 0u) << "the live-points must hold tile pixels for the round trip to test them";
  const std::string a = temp_path("tiles-a.rlp"), b = temp_path("tiles-b.rlp");
  write_livepoints(a, lib);
  const LivePoints back = read_livepoints(a);
  EXPECT_EQ(libraries_differ(lib, back), "");
  write_livepoints(b, back);
  EXPECT_EQ(read_bytes(a), read_bytes(b)) << "the same library gives the same bytes";
  for (size_t k = 0; k < lib.points.size(); ++k) {
    const UnitRun x = simulate_livepoint(lib, k, hw), y = simulate_livepoint(back, k, hw);
    EXPECT_EQ(warm_states_differ(x.warmed, y.warmed), "") << "unit " << k;
    EXPECT_EQ(x.total_cycles, y.total_cycles) << "unit " << k;
  }
  // The comparison can fail: a changed tile depth is found and named.
  LivePoints changed = read_livepoints(a);
  for (LivePoint& lp : changed.points)
    if (lp.tiles.size()) {
      lp.tiles.depth[0] = lp.tiles.depth[0] == 0.5f ? 0.25f : 0.5f;
      break;
    }
  EXPECT_NE(libraries_differ(lib, changed).find("tile pixels' depths"), std::string::npos);
  std::filesystem::remove(a);
  std::filesystem::remove(b);
}

// The approximate fidelity models compression and Hi-Z: every method with a
// pipeline runs on the current-GPU design with the golden image and
// counters, its Hi-Z rejections never reject a fragment that passes (the
// model throws InternalError otherwise), and it reports the compressed
// traffic (slab's layers are not compressed).
TEST(CompressionFidelities, ApproximateRunsEveryMethodWithCompressionAndHiz) {
  const HwConfig hw = default_design();
  for (const char* s : {"eight-layers", "opaque"})
    for (Method m : {Method::kOpaque, Method::kA2c, Method::kEnderton, Method::kLk, Method::kHashed, Method::kHashedA2c,
                     Method::kSlab, Method::kWboit, Method::kLkDepthAc, Method::kEndertonAc, Method::kBlend}) {
      const std::string what = std::string(s) + " 4 spp " + to_string(m) + " on the default design";
      const InputSpec in = scene_input(s, 4);
      const FunctionalRun golden = run_functional(in, method_config(m));
      ApproxRun a;
      ASSERT_NO_THROW(a = run_approximate(in, method_config(m), hw)) << what;
      EXPECT_TRUE(golden.image == a.image) << what << ": the approximate image is not the golden image";
      EXPECT_EQ(golden.counters.samples_written, a.counters.samples_written) << what;
      EXPECT_TRUE(a.stats.compression_on) << what << ": no compression figures";
      uint64_t lines = 0;
      for (size_t b = 0; b < size_t(kBuffers); ++b) lines += a.stats.compression.lines_written[b];
      if (m != Method::kSlab) {  // slab writes its layers, which are not compressed
        EXPECT_GT(lines, 0u) << what << ": no compressed line was written back";
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
