// Surface compression and Hi-Z: the encoders on crafted traces, Hi-Z's
// rejections, the uncompressed baseline against the golden model, and
// compression in the sampled and approximate fidelities.
#include "tests/cycle_test_util.h"

using namespace ropsim;
using namespace cycle_test;

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
      EXPECT_EQ(ropsim_test::first_image_difference(golden.image, a.image), "")
          << what << ": the approximate image is not the golden image";
      EXPECT_EQ(golden.counters.samples_written, a.counters.samples_written) << what;
      EXPECT_TRUE(a.stats.compression_on) << what << ": no compression figures";
      uint64_t lines = 0;
      for (size_t b = 0; b < size_t(kBuffers); ++b) lines += a.stats.compression.lines_written[b];
      if (m != Method::kSlab) {  // slab writes its layers, which are not compressed
        EXPECT_GT(lines, 0u) << what << ": no compressed line was written back";
      }
    }
}
