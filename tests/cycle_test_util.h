// Helpers shared by the cycle model's tests (test_cycle_*.cpp): the committed
// designs, bit-exactness against the golden model, the scene inputs, the mixed
// draw-state frame, timing and live-point library comparisons.
#pragma once
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
#include "tests/compare_util.h"
#include "tests/vcd_reader.h"
#include "traces/raster/rasterizer.h"
#include "traces/raster/sample_patterns.h"
#include "util/errors.h"

namespace cycle_test {

using namespace ropsim;

inline const std::string kSource = ROPSIM_SOURCE_DIR;

/// hw without compression and Hi-Z (as configs/uncompressed.toml).
inline HwConfig without_compression(HwConfig hw) {
  for (const char* a : {"compression.depth=false", "compression.color=false", "hiz.enable=false"})
    apply_hw_override(hw, a);
  return hw;
}

inline std::vector<std::string> config_files() {
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
inline std::vector<std::string> timing_config_files() {
  std::vector<std::string> v;
  for (const auto& f : config_files())
    if (std::filesystem::path(f).filename() != "uncompressed.toml") v.push_back(f);
  return v;
}

inline GoldenConfig method_config(Method m, const BlendFormats& formats = {},
                                  EndertonSelection sel = EndertonSelection::kDepthFirst) {
  GoldenConfig c;
  c.method = m;
  c.formats = formats;
  c.enderton_selection = sel;
  return c;
}

inline void expect_bit_exact(const TraceHeader& header, const std::vector<Fragment>& frags, const GoldenConfig& cfg,
                             const HwConfig& hw, const std::string& what, bool lockstep,
                             const std::function<CycleRun(const CycleOptions&)>& cycle);

/// Golden and cycle runs of one input; fails naming the first difference in
/// the full per-sample state, the image or the counters. A multi-pass method
/// replays the input once per pass in both.
inline void expect_bit_exact(const InputSpec& in, const GoldenConfig& cfg, const HwConfig& hw, const std::string& what,
                             bool lockstep = false) {
  const FragmentList list = load_fragments(in);
  expect_bit_exact(list.header, list.fragments, cfg, hw, what, lockstep,
                   [&](const CycleOptions& opt) { return run_cycle(in, cfg, hw, opt); });
}

/// The same for fragments held in memory (their header's draw states included).
inline void expect_bit_exact(const TraceHeader& h, const std::vector<Fragment>& frags, const GoldenConfig& cfg,
                             const HwConfig& hw, const std::string& what, bool lockstep = false) {
  expect_bit_exact(h, frags, cfg, hw, what, lockstep, [&](const CycleOptions& opt) {
    return run_cycle([&] { return fragments_from(h, frags); }, cfg, hw, opt);
  });
}

inline void expect_bit_exact(const TraceHeader& header, const std::vector<Fragment>& frags, const GoldenConfig& cfg,
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
  EXPECT_EQ(ropsim_test::first_image_difference(golden.resolve(), cyc.image), "") << what << ": resolved images differ";
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
inline void expect_bit_exact(const InputSpec& in, Method m, const HwConfig& hw, const std::string& what,
                             bool lockstep = false, EndertonSelection sel = EndertonSelection::kDepthFirst) {
  expect_bit_exact(in, method_config(m, hw.blend.formats, sel), hw, what, lockstep);
}

inline InputSpec scene_input(const std::string& name, int spp, uint32_t repeat = 1) {
  InputSpec in;
  in.scene.name = name;
  in.scene.spp = spp;
  in.repeat = repeat;
  return in;
}

/// A frame of mixed draw states (blend's test input): 24 x 20 pixels, eight
/// draws of overlapping rectangles with sloped depth and partial coverage,
/// drawn with blending off and on (src-over, additive, multiply, MIN/MAX,
/// constant colour, SRC_ALPHA_SATURATE), depth functions LESS, GREATER,
/// LEQUAL, ALWAYS and off, writes on and off, a colour mask; every draw into
/// a target of encoding e. Fixed seed.
inline std::pair<TraceHeader, std::vector<Fragment>> mixed_state_frame(int spp, TargetEncoding e) {
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

inline TraceHeader small_header(int spp) {
  TraceHeader h;
  h.width = 64;
  h.height = 64;
  h.spp = spp;
  h.positions = standard_sample_positions(spp);
  return h;
}

/// Every timing figure of two runs, activations aside; fails naming the first
/// that differs.
inline void expect_same_timing(const CycleStats& a, const CycleStats& b, const std::string& what) {
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

/// Every field of two fragments, bit for bit: "" or the first that differs, with both values.
inline std::string fragment_difference(const Fragment& a, const Fragment& b) {
  return ropsim_test::Fields()
      .eq("draw_id", a.draw_id, b.draw_id)
      .eq("prim_id", a.prim_id, b.prim_id)
      .eq("x", a.x, b.x)
      .eq("y", a.y, b.y)
      .eq("coverage", a.coverage, b.coverage)
      .bits("z0", a.z0, b.z0)
      .bits("dzdx", a.dzdx, b.dzdx)
      .bits("dzdy", a.dzdy, b.dzdy)
      .bits("z", a.z, b.z)
      .bits("rgb", a.rgb, b.rgb)
      .bits("alpha", a.alpha, b.alpha)
      .str();
}

/// Two libraries hold the same live-points, bit for bit; "" or the first difference.
inline std::string libraries_differ(const LivePoints& a, const LivePoints& b) {
  if (a.fragments != b.fragments || a.points.size() != b.points.size()) return "sizes";
  if (a.input.digest != b.input.digest || a.input.description != b.input.description) return "input";
  if (const std::string d = ropsim_test::first_image_difference(a.image, b.image); !d.empty()) return "image: " + d;
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
      if (const std::string d = fragment_difference(p.fragments[i], q.fragments[i]); !d.empty())
        return u + "fragment " + std::to_string(i) + ": " + d;
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

inline std::string temp_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("ropsim-test-" + std::to_string(::getpid()) + "-" + name)).string();
}

inline std::string read_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

}  // namespace cycle_test
