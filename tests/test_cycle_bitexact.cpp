// The cycle model against the golden model, bit for bit: every built-in scene
// x spp x method x committed design, frames of mixed draw states, the draw
// routes of every method, and extreme timing parameters.
#include "tests/cycle_test_util.h"

using namespace ropsim;
using namespace cycle_test;

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
