// Sampled simulation (livepoints.h): live-point units against the full cycle
// run and the golden state, the live-point library's file (round trip,
// refusals, forged fields), worker processes, and the estimates' statistics.
#include "tests/cycle_test_util.h"

using namespace ropsim;
using namespace cycle_test;

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
      EXPECT_EQ(ropsim_test::first_image_difference(lib.image, full.image), "")
          << what << ": the library holds the golden image";
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
        ASSERT_EQ(ropsim_test::Fields()
                      .eq("covered", a.covered, b.covered)
                      .eq("written", a.written, b.written)
                      .eq("reached_write", a.reached_write, b.reached_write)
                      .eq("routed", a.routed, b.routed)
                      .eq("reads_colour", a.reads_colour, b.reads_colour)
                      .eq("depth_write", a.depth_write, b.depth_write)
                      .str(),
                  "")
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
            ASSERT_EQ(ropsim_test::Fields()
                          .eq("x", a.x, b.x)
                          .eq("y", a.y, b.y)
                          .eq("covered", a.covered, b.covered)
                          .eq("written", a.written, b.written)
                          .eq("reached_write", a.reached_write, b.reached_write)
                          .eq("slab_kept", a.slab_kept, b.slab_kept)
                          .str(),
                      "")
                << unit << "warming touch " << i << " is not fragment " << from + i << "'s";
          }
          for (size_t i = 0; i < lp.fragments.size(); ++i) {
            Fragment want = all[lp.first + i];
            const bool per = h.depth_mode == DepthMode::kPerSample;
            for (size_t s = 0; s < want.z.size(); ++s)
              if (!per || s >= size_t(h.spp) || !(want.coverage >> s & 1)) want.z[s] = 0.0f;
            ASSERT_EQ(fragment_difference(lp.fragments[i], want), "")
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
