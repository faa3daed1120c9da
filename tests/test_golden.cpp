// The golden model: the properties Laine & Karras 2011 prove or claim, the
// comparison methods, and the numerical extremes.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "rtl_models/algo/half.h"
#include "rtl_models/algo/random_hash.h"
#include "rtl_models/golden/golden_model.h"
#include "sim/driver/pixel_kinds.h"
#include "sim/fidelity/functional/driver.h"
#include "sim/image/image_io.h"
#include "tests/compare_util.h"
#include "traces/raster/sample_patterns.h"

using namespace ropsim;

namespace {

TraceHeader header(uint32_t w, uint32_t h, int spp, std::array<float, 3> clear = {0, 0, 0}) {
  TraceHeader hd;
  hd.width = w;
  hd.height = h;
  hd.spp = spp;
  hd.positions = standard_sample_positions(spp);
  hd.clear_color = clear;
  return hd;
}

uint64_t full_mask(int spp) { return spp == 64 ? ~0ull : (1ull << spp) - 1; }

Fragment frag(uint32_t x, uint32_t y, uint64_t cov, float z, float alpha, std::array<float, 3> rgb = {1, 1, 1},
              uint32_t draw = 0, uint32_t prim = 0) {
  Fragment f;
  f.x = uint16_t(x);
  f.y = uint16_t(y);
  f.coverage = cov;
  f.z0 = z;
  f.rgb = rgb;
  f.alpha = alpha;
  f.draw_id = draw;
  f.prim_id = prim;
  return f;
}

StochasticModel model(const TraceHeader& h, Method m, Numerics num = {}, uint64_t seed = 1) {
  GoldenConfig c;
  c.method = m;
  c.numerics = num;
  c.seed = seed;
  return StochasticModel(h, c);
}

/// Samples of pixel (x, y) whose stored depth is z.
int samples_at_depth(const StochasticModel& m, uint32_t x, uint32_t y, float z) {
  auto v = m.pixel_view(x, y);
  if (!v.depth) return 0;
  int n = 0;
  for (int s = 0; s < m.header().spp; ++s) n += v.depth[s] == z;
  return n;
}

/// Splits a full pixel mask into k random disjoint non-empty parts.
std::vector<uint64_t> split_mask(uint64_t mask, int k, uint64_t key) {
  std::vector<uint64_t> parts(size_t(k), 0);
  int i = 0;
  for (uint64_t m = mask; m; m &= m - 1, ++i) {
    const uint64_t bit = m & (~m + 1);
    const int slot = i < k ? i : int(fragment_random(key, uint32_t(i)) % uint32_t(k));
    parts[size_t(slot)] |= bit;
  }
  std::vector<uint64_t> out;
  for (uint64_t p : parts)
    if (p) out.push_back(p);
  return out;
}

const float kAlphaSweep[] = {0.0f, 1e-6f, 0x1p-9f, 0.01f, 0.1f, 0.2f,  0.25f,        1.0f / 3.0f,
                             0.4f, 0.5f,  0.61f,   0.75f, 0.9f, 0.99f, 1.0f - 1e-6f, 1.0f};

}  // namespace

// One surface of opacity alpha, drawn as any number of triangles (disjoint
// coverage parts of one draw) into a pixel, covers exactly floor(aN) or ceil(aN)
// of its N samples -- in every pixel (LK §3-4).
TEST(LkStratification, OneSurfaceCoversFloorOrCeil) {
  for (int spp = 1; spp <= 64; spp *= 2) {
    for (float alpha : kAlphaSweep) {
      // Pixels near the origin, mid-screen and at the far corner of a large screen.
      TraceHeader h = header(4096, 4096, spp);
      StochasticModel m = model(h, Method::kLk);
      std::vector<std::pair<uint32_t, uint32_t>> pixels;
      for (uint32_t y = 0; y < 12; ++y)
        for (uint32_t x = 0; x < 12; ++x) {
          pixels.push_back({x, y});
          pixels.push_back({2000 + x, 1000 + y});
          pixels.push_back({4084 + x, 4084 + y});
        }
      uint32_t prim = 0;
      for (auto [x, y] : pixels) {
        const uint64_t key = fragment_key(99, 0, 0, x, y);
        const int k = 1 + int(fragment_random(key, 100) % 5);
        for (uint64_t part : split_mask(full_mask(spp), k, key))
          m.draw(frag(x, y, part, 0.5f, alpha, {1, 1, 1}, 0, prim++));
      }
      const double an = double(alpha) * spp;
      for (auto [x, y] : pixels) {
        const int c = samples_at_depth(m, x, y, 0.5f);
        EXPECT_TRUE(c == int(std::floor(an)) || c == int(std::ceil(an)))
            << "spp " << spp << " alpha " << alpha << " pixel (" << x << "," << y << ") covers " << c
            << " samples, expected floor/ceil of " << an;
      }
    }
  }
}

// LK §4: two full-pixel alpha = 0.5 surfaces at 16 spp leave the far one in
// exactly 4 samples, whichever is drawn first (sorting by stored depth).
TEST(LkStratification, FarSurfaceKeepsExactlyFourOfSixteen) {
  for (bool near_first : {true, false}) {
    TraceHeader h = header(64, 64, 16);
    StochasticModel m = model(h, Method::kLk);
    for (uint32_t y = 0; y < 64; ++y)
      for (uint32_t x = 0; x < 64; ++x) {
        Fragment nearf = frag(x, y, 0xFFFF, 0.25f, 0.5f, {1, 0, 0}, near_first ? 0 : 1);
        Fragment farf = frag(x, y, 0xFFFF, 0.75f, 0.5f, {0, 1, 0}, near_first ? 1 : 0);
        if (near_first) {
          m.draw(nearf);
          m.draw(farf);
        } else {
          m.draw(farf);
          m.draw(nearf);
        }
      }
    for (uint32_t y = 0; y < 64; ++y)
      for (uint32_t x = 0; x < 64; ++x) {
        ASSERT_EQ(samples_at_depth(m, x, y, 0.75f), 4)
            << (near_first ? "near first" : "far first") << " pixel " << x << "," << y;
        ASSERT_EQ(samples_at_depth(m, x, y, 0.25f), 8)
            << (near_first ? "near first" : "far first") << " pixel " << x << "," << y;
      }
  }
}

namespace {
/// Mean fraction of samples at depth z over a W x W region after drawing the
/// given layers (full-pixel fragments) in order.
struct Layer {
  float z, alpha;
};
double mean_coverage(Method meth, int spp, uint32_t W, const std::vector<Layer>& layers, float z_query,
                     Numerics num = {}) {
  TraceHeader h = header(W, W, spp);
  StochasticModel m = model(h, meth, num);
  for (uint32_t y = 0; y < W; ++y)
    for (uint32_t x = 0; x < W; ++x) {
      uint32_t d = 0;
      for (const Layer& l : layers) m.draw(frag(x, y, full_mask(spp), l.z, l.alpha, {1, 1, 1}, d++));
    }
  uint64_t n = 0;
  for (uint32_t y = 0; y < W; ++y)
    for (uint32_t x = 0; x < W; ++x) n += uint64_t(samples_at_depth(m, x, y, z_query));
  return double(n) / (double(W) * W * spp);
}
/// 6-sigma bound on the mean of M sample indicators with P(1) = p: stratified
/// (LK, Enderton) and independent (naive) sampling both have variance at most
/// the binomial p(1 - p) / M, so 6 sqrt(p (1 - p) / M) plus the 2^-32
/// quantisation of alpha bounds |mean - p| with probability > 1 - 1e-8.
double bound(double p, double samples) { return 6.0 * std::sqrt(std::max(p * (1 - p), 1e-12) / samples) + 0x1p-31; }
}  // namespace

TEST(Unbiased, OneSurfaceMeanCoverageIsAlpha) {
  for (Method meth : {Method::kLk, Method::kEnderton, Method::kNaive}) {
    for (float alpha : {0.0f, 1e-6f, 0x1p-9f, 0.25f, 0.61f, 1.0f - 1e-6f, 1.0f}) {
      const int spp = 16;
      const uint32_t W = (alpha > 0 && alpha < 1e-3f) || alpha > 0.999f ? 1024 : 256;
      const double mean = mean_coverage(meth, spp, W, {{0.5f, alpha}}, 0.5f);
      const double b = bound(alpha, double(W) * W * spp);
      EXPECT_NEAR(mean, double(alpha), b) << to_string(meth) << " alpha " << alpha << " (bound " << b << ")";
      if (alpha == 0.0f) {
        EXPECT_EQ(mean, 0.0) << to_string(meth) << ": alpha 0 must never write";
      }
      if (alpha == 1.0f) {
        EXPECT_EQ(mean, 1.0) << to_string(meth) << ": alpha 1 must always write";
      }
      if (alpha == 1e-6f) {
        EXPECT_GT(mean, 0.0) << to_string(meth) << ": alpha 1e-6 must still write sometimes";
      }
    }
  }
}

TEST(Unbiased, TwoLayersFarMeanIsAlphaFarTimesOneMinusAlphaNear) {
  const float a_near = 0.4f, a_far = 0.7f;
  const double expect = double(a_far) * (1.0 - double(a_near));
  for (Method meth : {Method::kLk, Method::kEnderton, Method::kNaive})
    for (int spp : {4, 16, 64})
      for (bool near_first : {true, false}) {
        std::vector<Layer> layers = {{0.2f, a_near}, {0.8f, a_far}};
        if (!near_first) std::swap(layers[0], layers[1]);
        const uint32_t W = 192;
        const double mean = mean_coverage(meth, spp, W, layers, 0.8f);
        EXPECT_NEAR(mean, expect, bound(expect, double(W) * W * spp))
            << to_string(meth) << " spp " << spp << (near_first ? " near first" : " far first");
      }
}

// Hundreds of layers, with an 8-bit surface id that wraps: still unbiased.
TEST(Unbiased, HundredsOfLayersWithSurfaceIdWrap) {
  std::vector<Layer> layers;
  for (int k = 0; k < 300; ++k) layers.push_back({1.0f - float(k + 1) / 512.0f, 0.01f});  // drawn far to near
  for (int sid_bits : {8, 32}) {
    Numerics num;
    num.surface_id_bits = sid_bits;
    // Coverage of the nearest layer only: alpha.
    const double near = mean_coverage(Method::kLk, 16, 48, layers, layers.back().z, num);
    EXPECT_NEAR(near, 0.01, bound(0.01, 48.0 * 48 * 16)) << "surface id bits " << sid_bits;
    // Total coverage of all layers: 1 - 0.99^300, from the resolve of white layers over black.
    TraceHeader h = header(48, 48, 16);
    StochasticModel m = model(h, Method::kLk, num);
    for (uint32_t y = 0; y < 48; ++y)
      for (uint32_t x = 0; x < 48; ++x) {
        uint32_t d = 0;
        for (const Layer& l : layers) m.draw(frag(x, y, 0xFFFF, l.z, l.alpha, {1, 1, 1}, d++));
      }
    const std::vector<float> px = m.resolve().dense();
    double sum = 0;
    for (float v : px) sum += v;
    const double mean = sum / px.size(), expect = 1.0 - std::pow(0.99, 300);
    EXPECT_NEAR(mean, expect, bound(expect, 48.0 * 48 * 16)) << "surface id bits " << sid_bits;
    EXPECT_GE(m.counters().surface_id_changes, 48u * 48 * 250) << "each layer should start a new surface";
  }
}

// Coplanar surfaces: the later one is in front (LESS_EQUAL), as in the reference.
TEST(Unbiased, DepthTiesMatchTheReference) {
  TraceHeader h = header(128, 128, 16);
  auto run = [&](Method meth) {
    GoldenConfig c;
    c.method = meth;
    auto m = make_functional_model(h, c);
    for (uint32_t y = 0; y < 128; ++y)
      for (uint32_t x = 0; x < 128; ++x) {
        m->draw(frag(x, y, 0xFFFF, 0.5f, 0.5f, {1, 0, 0}, 0));
        m->draw(frag(x, y, 0xFFFF, 0.5f, 0.5f, {0, 1, 0}, 1));
      }
    const std::vector<float> px = m->resolve().dense();
    std::array<double, 3> mean{};
    for (size_t i = 0; i < px.size(); ++i) mean[i % 3] += px[i] / (128.0 * 128);
    return mean;
  };
  const auto ref = run(Method::kReference);
  EXPECT_DOUBLE_EQ(ref[0], 0.25);
  EXPECT_DOUBLE_EQ(ref[1], 0.5);
  for (Method meth : {Method::kLk, Method::kEnderton, Method::kNaive}) {
    const auto got = run(meth);
    for (int c = 0; c < 2; ++c)
      EXPECT_NEAR(got[c], ref[c], bound(0.5, 128.0 * 128 * 16)) << to_string(meth) << " channel " << c;
  }
}

namespace {
std::array<double, 3> mean_pixel(const Image& img) {
  std::array<double, 3> m{};
  const std::vector<float> px = img.dense();
  for (size_t i = 0; i < px.size(); ++i) m[i % 3] += px[i];
  for (auto& v : m) v /= double(img.width) * img.height;
  return m;
}
}  // namespace

// Enderton et al. Examples 1 and 2: closed-form pixel values, on 256 x 256
// pixels at 4 spp, 128 x 128 at 16, 64 x 64 at 64 (the same 2^18 samples;
// fixed seed: the default).
TEST(EndertonExamples, MeanPixelMatchesClosedForm) {
  struct Ex {
    const char* scene;
    std::array<double, 3> exact;
  };
  const Ex examples[] = {{"enderton-1", {0.45, 0.2475, 0.3025}},
                         {"enderton-2", {0.7626953125, 0.7626953125, 0.7626953125}}};
  for (const auto& ex : examples)
    for (int spp : {4, 16, 64}) {
      InputSpec in;
      in.scene.name = ex.scene;
      in.scene.spp = spp;
      in.scene.width = in.scene.height = spp == 4 ? 256 : spp == 16 ? 128 : 64;
      GoldenConfig cfg;
      cfg.method = Method::kReference;
      FunctionalRun ref = run_functional(in, cfg);
      const std::vector<float> ref_px = ref.image.dense();
      for (size_t i = 0; i < ref_px.size(); ++i) {
        if (ex.scene == std::string("enderton-2"))
          ASSERT_EQ(ref_px[i], float(ex.exact[i % 3])) << ex.scene << ": the reference must be exact";
        else
          ASSERT_NEAR(ref_px[i], ex.exact[i % 3], 2e-8 + 1e-7) << ex.scene << ": reference (alpha = 0.45f)";
      }
      // The depth-based methods without alpha correction are unbiased too
      // (Enderton et al. 3.4: each fragment weighted by an unbiased estimate
      // of its visibility, the background by the uncovered fraction). The
      // biased ones (+ac, wboit) are not tested here.
      for (Method meth : {Method::kLk, Method::kEnderton, Method::kNaive, Method::kLkDepth, Method::kEndertonDepth}) {
        cfg.method = meth;
        FunctionalRun r = run_functional(in, cfg);
        const auto m = mean_pixel(r.image);
        const double n = double(r.header.width) * r.header.height;
        for (int c = 0; c < 3; ++c) {
          // Bound from the per-pixel variance: the pixels are independent
          // (each draws its own hashed random numbers), so the mean of the N
          // pixel values has standard error sqrt(s^2 / N), s^2 their sample
          // variance; 6 standard errors (a miss has probability < 1e-8 for a
          // normal mean) plus 1e-3 for the binary16 rounding of colours and
          // sums. The noise is below the bound less 1e-3, and the bound is
          // asserted below 0.0085 (it is 0.001-0.007 here), so a bias of 0.017
          // (enderton+ac's on Ex. 1, docs/results.md) exceeds bound plus noise
          // and fails: enderton+ac at 4 spp misses R by 0.0164, bound 0.0041.
          double s2 = 0;
          const std::vector<float> px = r.image.dense();
          for (size_t i = size_t(c); i < px.size(); i += 3) s2 += (px[i] - m[size_t(c)]) * (px[i] - m[size_t(c)]);
          s2 /= n - 1;
          const double b = 6 * std::sqrt(s2 / n) + 1e-3;
          EXPECT_LT(b, 0.0085) << ex.scene << " " << to_string(meth) << " spp " << spp << " channel " << c;
          EXPECT_NEAR(m[size_t(c)], ex.exact[size_t(c)], b)
              << ex.scene << " " << to_string(meth) << " spp " << spp << " channel " << c;
        }
      }
    }
}

// slab with k at least the number of layers is stochastic transparency with
// b samples, so its mean pixel is the exact composite in expectation. Bound:
// as above, with the W x H x b mask bits as the samples (the bits of one
// layer are stratified, at most the binomial variance; layers independent).
TEST(Slab, KLargeMeanPixelIsTheExactComposite) {
  struct Ex {
    const char* scene;
    std::array<double, 3> exact;
  };
  const Ex examples[] = {{"enderton-1", {0.45, 0.2475, 0.3025}},
                         {"enderton-2", {0.7626953125, 0.7626953125, 0.7626953125}}};
  for (const auto& ex : examples)
    for (int spp : {1, 4})
      for (int bits : {8, 32}) {
        InputSpec in;
        in.scene.name = ex.scene;
        in.scene.spp = spp;
        in.scene.width = in.scene.height = 128;
        GoldenConfig cfg;
        cfg.method = Method::kSlab;
        cfg.slab_layers = 16;
        cfg.slab_bits = bits;
        FunctionalRun r = run_functional(in, cfg);
        const auto m = mean_pixel(r.image);
        const double samples = double(r.header.width) * r.header.height * bits;
        const double b = 4 * bound(0.5, samples) + 1e-3;
        for (int c = 0; c < 3; ++c)
          EXPECT_NEAR(m[size_t(c)], ex.exact[size_t(c)], b)
              << ex.scene << " spp " << spp << " b " << bits << " channel " << c << " (bound " << b << ")";
      }
}

// slab with k = 1 on opaque input keeps the nearest fragment of each pixel: at
// 1 spp exactly the z-buffer's image.
TEST(Slab, KOneOnOpaqueInputIsTheZBufferImage) {
  InputSpec in;
  in.scene.name = "opaque";
  in.scene.spp = 1;
  GoldenConfig cfg;
  cfg.method = Method::kOpaque;
  const Image zbuf = run_functional(in, cfg).image;
  cfg.method = Method::kSlab;
  cfg.slab_layers = 1;
  for (int bits : {1, 32}) {
    cfg.slab_bits = bits;
    EXPECT_EQ(ropsim_test::first_image_difference(run_functional(in, cfg).image, zbuf), "") << "b " << bits;
  }
}

// LK Table 1 on the built-in cloth: lk beats enderton at every spp, and the
// ratio lk / enderton falls as spp rises (seeds fixed; see docs/results.md).
TEST(ClothRmse, LkBeatsEndertonAndTheRatioFalls) {
  double prev_ratio = 1e9;
  for (int spp : {4, 16, 64}) {
    InputSpec in;
    in.scene.name = "cloth";
    in.scene.spp = spp;
    GoldenConfig cfg;
    cfg.method = Method::kLk;
    FunctionalRun lk = run_functional(in, cfg, true);
    cfg.method = Method::kEnderton;
    FunctionalRun en = run_functional(in, cfg, true);
    const double r_lk = compare_images(lk.image, *lk.reference).rmse_8bit;
    const double r_en = compare_images(en.image, *en.reference).rmse_8bit;
    EXPECT_LT(r_lk, r_en) << "spp " << spp << ": lk RMSE " << r_lk << " vs enderton " << r_en;
    const double ratio = r_lk / r_en;
    EXPECT_LT(ratio, prev_ratio) << "spp " << spp << ": the ratio lk/enderton must fall as spp rises";
    prev_ratio = ratio;
  }
}

TEST(Methods, AlphaOneIsAPlainZBuffer) {
  // On opaque geometry lk, enderton, naive and a2c all write exactly what the z-buffer writes.
  InputSpec in;
  in.scene.name = "opaque";
  in.scene.spp = 8;
  GoldenConfig cfg;
  cfg.method = Method::kOpaque;
  const Image zbuf = run_functional(in, cfg).image;
  for (Method meth :
       {Method::kLk, Method::kEnderton, Method::kNaive, Method::kA2c, Method::kHashed, Method::kHashedA2c}) {
    cfg.method = meth;
    EXPECT_EQ(ropsim_test::first_image_difference(run_functional(in, cfg).image, zbuf), "") << to_string(meth);
  }
  cfg.method = Method::kReference;
  const Image ref = run_functional(in, cfg).image;
  EXPECT_LT(compare_images(zbuf, ref).max_error_8bit, 0.26) << "z-buffer vs A-buffer differ beyond binary16 rounding";
}

TEST(Methods, A2cHasStaticAssignment) {
  // Two same-alpha surfaces: a2c writes the same samples twice, so the far one
  // vanishes (the failure LK §1.1 describes); lk keeps alpha_far (1 - alpha_near).
  const double far_a2c = mean_coverage(Method::kA2c, 16, 64, {{0.2f, 0.5f}, {0.8f, 0.5f}}, 0.8f);
  EXPECT_EQ(far_a2c, 0.0);
  const double far_lk = mean_coverage(Method::kLk, 16, 64, {{0.2f, 0.5f}, {0.8f, 0.5f}}, 0.8f);
  EXPECT_NEAR(far_lk, 0.25, 1e-9);
  // One surface: a2c coverage is alpha within the dither's resolution.
  EXPECT_NEAR(mean_coverage(Method::kA2c, 16, 64, {{0.5f, 0.3f}}, 0.5f), 0.3, 1.0 / 32);
}

// Wyman & McGuire 2017 §8: two overlapping alpha 0.5 surfaces. hashed-a2c
// draws each fragment's stratum order from its own hash, so the two masks are
// independent and the union covers 1 - 0.5^2 = 0.75 of the samples in
// expectation; a2c's fixed dither gives both the same samples: exactly 0.5.
// Bound: per pixel the uncovered count lies in [0, spp/2], so its variance is
// at most spp^2/16 (Popoviciu) and the mean fraction over P pixels has
// sigma <= 1/(4 sqrt(P)); 6 sigma with P = 128^2 is 0.0117.
TEST(Methods, HashedA2cDecorrelatesOverlappingSurfaces) {
  const uint32_t W = 128;
  const double b = 6.0 / (4.0 * std::sqrt(double(W) * W));
  for (int spp : {4, 16, 64}) {
    auto union_coverage = [&](Method meth) {
      const std::vector<Layer> layers = {{0.2f, 0.5f}, {0.8f, 0.5f}};
      return mean_coverage(meth, spp, W, layers, 0.2f) + mean_coverage(meth, spp, W, layers, 0.8f);
    };
    EXPECT_NEAR(union_coverage(Method::kHashedA2c), 0.75, b) << spp << " spp (bound " << b << ")";
    EXPECT_EQ(union_coverage(Method::kA2c), 0.5) << spp << " spp: a2c's known correlation";
  }
}

// hashed: one threshold per fragment, so a pixel is all or nothing; the mean
// over pixels is alpha (6-sigma binomial bound over the W^2 pixels, not the
// samples). hashed-a2c: alpha within the stratified bound over the samples.
TEST(Unbiased, HashedMethodsMeanCoverageIsAlpha) {
  const int spp = 16;
  const uint32_t W = 256;
  for (float alpha : {0.0f, 0.25f, 0.61f, 1.0f}) {
    const double hashed = mean_coverage(Method::kHashed, spp, W, {{0.5f, alpha}}, 0.5f);
    EXPECT_NEAR(hashed, double(alpha), bound(alpha, double(W) * W)) << "hashed alpha " << alpha;
    const double ha2c = mean_coverage(Method::kHashedA2c, spp, W, {{0.5f, alpha}}, 0.5f);
    EXPECT_NEAR(ha2c, double(alpha), bound(alpha, double(W) * W * spp)) << "hashed-a2c alpha " << alpha;
  }
  // All or nothing per pixel: every touched pixel has 0 or spp samples of the surface.
  TraceHeader h = header(64, 64, spp);
  StochasticModel m = model(h, Method::kHashed);
  for (uint32_t y = 0; y < 64; ++y)
    for (uint32_t x = 0; x < 64; ++x) m.draw(frag(x, y, full_mask(spp), 0.5f, 0.5f));
  for (uint32_t y = 0; y < 64; ++y)
    for (uint32_t x = 0; x < 64; ++x) {
      const int n = samples_at_depth(m, x, y, 0.5f);
      ASSERT_TRUE(n == 0 || n == spp) << "hashed kept " << n << " of " << spp << " samples at " << x << "," << y;
    }
}

TEST(Determinism, SameSeedSameBitsOtherSeedOtherBits) {
  InputSpec in;
  in.scene.name = "smoke";
  in.scene.spp = 4;
  GoldenConfig cfg;
  cfg.method = Method::kEnderton;
  const Image a = run_functional(in, cfg).image, b = run_functional(in, cfg).image;
  EXPECT_EQ(ropsim_test::first_image_difference(a, b), "") << "the same seed gave another image";
  cfg.seed = 2;
  EXPECT_TRUE(run_functional(in, cfg).image != a) << "--seed must change the random numbers";
  in.scene.seed = 7;
  cfg.seed = 1;
  EXPECT_TRUE(run_functional(in, cfg).image != a) << "the scene seed must change the scene";
}

// State exists only for touched tiles: a huge screen costs what it touches.
TEST(Sparse, StateFollowsTouchedTiles) {
  TraceHeader h = header(32768, 32768, 64);
  StochasticModel m = model(h, Method::kLk);
  for (uint32_t x = 0; x < 8; ++x) m.draw(frag(32760 + x, 32767, ~0ull, 0.5f, 0.5f));
  m.draw(frag(0, 0, ~0ull, 0.5f, 0.5f));
  EXPECT_EQ(m.counters().tiles_touched, 2u);
  EXPECT_LT(m.state_bytes(), 1u << 20) << "two tiles of a 32768^2 screen must not cost the whole screen";
  // pixelId * spp overflows 32 bits here; the pixel is still exactly stratified.
  EXPECT_EQ(samples_at_depth(m, 32767, 32767, 0.5f), 32);
  EXPECT_EQ(m.pixel_view(100, 100).depth, nullptr);
}

TEST(Sparse, TenPercentOf4kAt64SppFitsInOneGiB) {
  TraceHeader h = header(3840, 2160, 64);
  StochasticModel m = model(h, Method::kLk);
  const uint32_t rows = 216;  // 10 % of the screen
  for (uint32_t y = 1000; y < 1000 + rows; ++y)
    for (uint32_t x = 0; x < 3840; ++x) m.draw(frag(x, y, ~0ull, 0.5f, 1.0f));
  EXPECT_LT(m.state_bytes(), size_t(1) << 30) << "state for 10% of a 4K 64-spp screen";
  EXPECT_LT(m.state_bytes(), size_t(3840) * 224 * 64 * 10 + (size_t(64) << 20));
}

// Regression: a per-sample-depth trace once sent the model into endless
// recursion. Both depth encodings of one scene must give the same state.
TEST(DepthModes, PerSampleTraceGivesThePlaneTracesImage) {
  const std::string dir = ::testing::TempDir();
  Image img[2];
  for (int k = 0; k < 2; ++k) {
    SceneParams p;
    p.name = "eight-layers";
    p.spp = 8;
    p.depth_mode = k ? DepthMode::kPerSample : DepthMode::kPlane;
    const std::string path = dir + "/depthmode" + std::to_string(k) + ".rtr";
    write_scene_trace(p, path);
    InputSpec in;
    in.trace_path = path;
    GoldenConfig c;
    img[k] = run_functional(in, c).image;
  }
  ASSERT_EQ(img[0].width, img[1].width);
  EXPECT_EQ(ropsim_test::first_image_difference(img[0], img[1]), "")
      << "plane and per-sample depth traces of one scene resolve differently";
}

// Bias: the mean signed error, zero for equal images, its sign the direction.
TEST(CompareImages, BiasIsTheMeanSignedErrorIn8BitUnits) {
  const Image a(4, 2, {0.5f, 0.5f, 0.5f});
  Image b = a;
  EXPECT_EQ(compare_images(a, b).bias_8bit, 0.0);
  for (size_t i = 0; i < 4 * 2 * 3; i += 2)
    b.at(uint32_t(i / 3 % 4), uint32_t(i / 12))[i % 3] += 0.1f;  // half the channels brighter by 0.1
  EXPECT_NEAR(compare_images(b, a).bias_8bit, 0.05 * 255, 1e-3);
  EXPECT_NEAR(compare_images(a, b).bias_8bit, -0.05 * 255, 1e-3);
  EXPECT_GT(compare_images(a, b).rmse_8bit, 0.0);
}

// Pixel kinds: each rule on a crafted trace, and the RMSE restricted to a kind.
TEST(PixelKinds, EachKindOnACraftedTraceAndTheErrorWithinIt) {
  TraceHeader h;
  h.width = 8;
  h.height = 1;
  h.spp = 4;
  h.positions = standard_sample_positions(4);
  const std::string path = ::testing::TempDir() + "pixel_kinds_" + std::to_string(::getpid()) + ".rtr";
  {
    TraceWriter w(path, h);
    auto frag = [&](uint16_t x, uint64_t cov, float z) {
      Fragment f;
      f.x = x;
      f.coverage = cov;
      f.z0 = z;
      f.rgb = {0.5f, 0.5f, 0.5f};
      f.alpha = 0.5f;
      w.write(f);
    };
    frag(0, 0xF, 0.5f);                                          // single layer
    frag(1, 0x3, 0.5f), frag(1, 0xC, 0.5f);                      // interior edge
    frag(2, 0x7, 0.5f);                                          // silhouette
    frag(3, 0xF, 0.8f), frag(3, 0xF, 0.2f);                      // two layers, the later nearer
    frag(4, 0xF, 0.2f), frag(4, 0xF, 0.8f);                      // two layers, the later farther
    frag(5, 0xF, 0.3f), frag(5, 0xF, 0.2f), frag(5, 0xF, 0.1f);  // three layers
    w.finish();
  }
  InputSpec in;
  in.trace_path = path;
  const PixelKinds k = classify_pixels(in);
  std::remove(path.c_str());
  const PixelKind want[8] = {PixelKind::kSingle,       PixelKind::kInteriorEdge, PixelKind::kSilhouette,
                             PixelKind::kTwoFarToNear, PixelKind::kTwoNearToFar, PixelKind::kMany,
                             PixelKind::kEmpty,        PixelKind::kEmpty};
  ASSERT_EQ(k.kind.size(), 8u);
  for (int i = 0; i < 8; ++i)
    EXPECT_EQ(k.kind[size_t(i)], want[i]) << "pixel " << i << ": " << to_string(k.kind[size_t(i)]);
  EXPECT_EQ(k.count[size_t(PixelKind::kEmpty)], 2u);
  const Image ref(8, 1, {0.25f, 0.25f, 0.25f});
  Image img = ref;
  img.at(3, 0)[1] += 0.3f;  // one channel of the far-to-near pixel
  const auto r = rmse_by_kind(k, img, ref);
  for (int j = 0; j < kPixelKinds; ++j)
    if (PixelKind(j) == PixelKind::kTwoFarToNear)
      EXPECT_NEAR(r[size_t(j)], std::sqrt(0.3 * 0.3 / 3.0) * 255.0, 1e-3);
    else
      EXPECT_EQ(r[size_t(j)], 0.0) << to_string(PixelKind(j));
}

// ------------------------------------------------------------ blend passes

namespace {

/// A golden run over a fragment list, every pass replaying it.
Image run_passes(const TraceHeader& h, Method m, const std::vector<Fragment>& frags, BlendFormats formats = {}) {
  GoldenConfig c;
  c.method = m;
  c.formats = formats;
  StochasticModel model(h, c);
  for (int pass = 0; pass < model.passes(); ++pass) {
    model.begin_pass(pass);
    for (const auto& f : frags) model.draw(f);
  }
  return model.resolve();
}

struct BlendLayer {
  float z, alpha;
  std::array<float, 3> rgb;
};

}  // namespace

// Weighted blended OIT (McGuire & Bavoil 2013, Eq. 6 with the weight of
// Eq. 10): C = sum(a_i c_i w_i) / sum(a_i w_i) (1 - prod(1 - a_i)) + prod(1 -
// a_i) background, w_i = a_i max(1e-2, 3e3 (1 - z_i)^3), computed here in
// double. Per-sample targets hold binary16: each stored sum is rounded to 11
// significant bits after each of at most 3 additions, so the ratio is within
// a relative 4 x 3 x 2^-11 of the exact one (<= 6e-3 of a colour <= 1); with
// binary32 targets within 1e-5.
TEST(Wboit, MatchesItsClosedFormOnTwoAndThreeLayers) {
  const std::array<float, 3> bg = {0.25f, 0.25f, 0.25f};  // exact in binary16
  const std::vector<std::vector<BlendLayer>> cases = {
      {{0.3f, 0.5f, {1, 0, 0}}, {0.6f, 0.4f, {0, 1, 0}}},
      {{0.6f, 0.4f, {0, 1, 0}}, {0.3f, 0.5f, {1, 0, 0}}},  // the same, drawn far first
      {{0.1f, 0.25f, {0, 0, 1}}, {0.5f, 0.75f, {1, 1, 0}}, {0.9f, 0.6f, {0.2f, 0.7f, 0.4f}}},
      {{0.95f, 0.3f, {1, 1, 1}}, {0.05f, 0.9f, {0.5f, 0, 0.5f}}, {0.4f, 0.1f, {0, 0.3f, 0}}},
  };
  for (const auto& layers : cases) {
    double num[3] = {0, 0, 0}, den = 0, T = 1;
    for (const auto& l : layers) {
      const double w = l.alpha * std::max(1e-2, 3e3 * std::pow(1.0 - l.z, 3));
      for (int c = 0; c < 3; ++c) num[c] += double(l.alpha) * l.rgb[size_t(c)] * w;
      den += double(l.alpha) * w;
      T *= 1.0 - l.alpha;
    }
    for (int spp : {1, 4, 16}) {
      const TraceHeader h = header(4, 4, spp, bg);
      std::vector<Fragment> frags;
      for (uint32_t y = 0; y < 4; ++y)
        for (uint32_t x = 0; x < 4; ++x) {
          uint32_t d = 0;
          for (const auto& l : layers) frags.push_back(frag(x, y, full_mask(spp), l.z, l.alpha, l.rgb, d++));
        }
      for (bool wide : {false, true}) {
        BlendFormats f;
        if (wide) f = {TargetFormat::kR32F, TargetFormat::kRGBA32F};
        const std::vector<float> px = run_passes(h, Method::kWboit, frags, f).dense();
        const double tol = wide ? 1e-5 : 6e-3;
        for (size_t i = 0; i < px.size(); ++i) {
          const int c = int(i % 3);
          const double exact = num[c] / den * (1.0 - T) + T * bg[size_t(c)];
          ASSERT_NEAR(px[i], exact, tol) << layers.size() << " layers, spp " << spp << (wide ? " r32f" : " r16f")
                                         << " channel " << c;
        }
      }
    }
  }
}

// Alpha correction (Enderton et al. 3.3): a pixel with a single transparent
// layer is exact, alpha c + (1 - alpha) background, whatever samples the
// stochastic pass chose -- as long as it chose one: with the stratified count
// floor(alpha S + xi) that holds for alpha >= 1/S (+ac); the depth-based
// variants accumulate every covered sample, so any alpha. The bound is the
// binary16 rounding of the stored transmittance (2^-11 relative) and colour.
TEST(AlphaCorrection, ASingleTransparentLayerIsExact) {
  const std::array<float, 3> bg = {0.0f, 0.0f, 1.0f};
  const std::array<float, 3> rgb = {1.0f, 0.5f, 0.0f};
  for (Method m : {Method::kLkAc, Method::kEndertonAc, Method::kLkDepthAc, Method::kEndertonDepthAc})
    for (int spp : {1, 4, 16, 64})
      for (float alpha : {0.05f, 0.3f, 0.45f, 0.7f, 0.95f, 1.0f}) {
        if (!traits(m).depth_based && alpha * float(spp) < 1.0f) continue;  // the stochastic pass may write nothing
        const TraceHeader h = header(16, 16, spp, bg);
        std::vector<Fragment> frags;
        for (uint32_t y = 0; y < 16; ++y)
          for (uint32_t x = 0; x < 16; ++x)
            frags.push_back(frag(x, y, full_mask(spp), 0.5f, alpha, rgb, 0, y * 16 + x));
        const std::vector<float> px = run_passes(h, m, frags).dense();
        for (size_t i = 0; i < px.size(); ++i) {
          const int c = int(i % 3);
          const double exact = double(alpha) * rgb[size_t(c)] + (1.0 - alpha) * bg[size_t(c)];
          ASSERT_NEAR(px[i], exact, 2e-3)
              << to_string(m) << " spp " << spp << " alpha " << alpha << " channel " << c << " pixel " << i / 3;
        }
      }
  // Without the correction a single layer is noisy: lk at 4 spp and alpha 0.3
  // writes 1 or 2 samples, never 1.2 -- so some pixel is off by >= 0.05.
  const TraceHeader h = header(16, 16, 4, bg);
  std::vector<Fragment> frags;
  for (uint32_t y = 0; y < 16; ++y)
    for (uint32_t x = 0; x < 16; ++x) frags.push_back(frag(x, y, 0xF, 0.5f, 0.3f, rgb, 0, y * 16 + x));
  const std::vector<float> px = run_passes(h, Method::kLk, frags).dense();
  double worst = 0;
  for (size_t i = 0; i < px.size(); i += 3) worst = std::max(worst, std::fabs(px[i] - 0.3));
  EXPECT_GE(worst, 0.05) << "lk without alpha correction should not be exact on a single layer";
}

// The blend passes' depth test does not write: the accumulation pass leaves
// the stochastic depth as it is, and a total-alpha pass alone leaves the
// clear depth.
TEST(BlendPasses, TheirDepthTestDoesNotWrite) {
  const TraceHeader h = header(8, 8, 4);
  std::vector<Fragment> frags;
  for (uint32_t y = 0; y < 8; ++y)
    for (uint32_t x = 0; x < 8; ++x) {
      frags.push_back(frag(x, y, 0xF, 0.7f, 0.5f, {1, 0, 0}, 0, x));
      frags.push_back(frag(x, y, 0xF, 0.3f, 0.5f, {0, 1, 0}, 1, x));
    }
  GoldenConfig c;
  c.method = Method::kWboit;
  StochasticModel wb(h, c);
  for (const auto& f : frags) wb.draw(f);
  EXPECT_EQ(samples_at_depth(wb, 3, 3, 1.0f), 4) << "wboit wrote depth";
  EXPECT_EQ(wb.counters().samples_blended, 2u * 4 * 64) << "every covered sample passes a non-writing depth test";
  c.method = Method::kLkDepth;
  StochasticModel ld(h, c);
  ld.begin_pass(0);
  for (const auto& f : frags) ld.draw(f);
  std::vector<float> after_stochastic;
  for (uint32_t y = 0; y < 8; ++y)
    for (uint32_t x = 0; x < 8; ++x) {
      const auto v = ld.pixel_view(x, y);
      after_stochastic.insert(after_stochastic.end(), v.depth, v.depth + 4);
    }
  ld.begin_pass(1);
  for (const auto& f : frags) ld.draw(f);
  size_t k = 0;
  for (uint32_t y = 0; y < 8; ++y)
    for (uint32_t x = 0; x < 8; ++x) {
      const auto v = ld.pixel_view(x, y);
      for (int s = 0; s < 4; ++s) ASSERT_EQ(v.depth[s], after_stochastic[k++]) << "the accumulation pass wrote depth";
    }
  EXPECT_EQ(ld.counters().color_bytes_written, 0u) << "a depth-based stochastic pass stores depth only";
}

// ------------------------------------------------------------ Enderton et al.'s RMS errors

namespace {

/// Per-channel RMS error of a method's image against the exact pixel over the
/// pixels of the example where every fragment covers the whole pixel (the
/// rectangles' two triangles split the diagonal's pixels into two fragments
/// each, which the paper's examples do not have), S = 4, 512 x 512 pixels.
std::array<double, 3> example_rms(const char* scene, Method m, size_t* pixels) {
  // Each scene is made once for all its methods.
  static std::map<std::string, FragmentList> made;
  auto it = made.find(scene);
  if (it == made.end()) {
    InputSpec in;
    in.scene.name = scene;
    in.scene.spp = 4;
    in.scene.width = in.scene.height = 512;
    it = made.emplace(scene, load_fragments(in)).first;
  }
  const FragmentList& list = it->second;
  std::vector<bool> split(size_t(512) * 512, false);
  for (const auto& f : list.fragments)
    if (f.coverage != 0xF) split[size_t(f.y) * 512 + f.x] = true;
  GoldenConfig cfg;
  cfg.method = m;
  cfg.enderton_selection = EndertonSelection::kOriginal;
  StochasticModel model(list.header, cfg);
  for (int pass = 0; pass < model.passes(); ++pass) {
    model.begin_pass(pass);
    for (const auto& f : list.fragments) model.draw(f);
  }
  const Image img = model.resolve();
  const std::array<double, 3> exact = std::string(scene) == "enderton-1"
                                          ? std::array<double, 3>{0.45, 0.2475, 0.3025}
                                          : std::array<double, 3>{0.7626953125, 0.7626953125, 0.7626953125};
  std::array<double, 3> e{};
  size_t n = 0;
  for (uint32_t y = 0; y < 512; ++y)
    for (uint32_t x = 0; x < 512; ++x) {
      if (split[size_t(y) * 512 + x]) continue;
      ++n;
      for (int c = 0; c < 3; ++c) {
        const double d = img.at(x, y)[c] - exact[size_t(c)];
        e[size_t(c)] += d * d;
      }
    }
  for (auto& v : e) v = std::sqrt(v / double(n));
  *pixels = n;
  return e;
}

}  // namespace

// Enderton et al.'s Examples 1 and 2 at S = 4 (every sample at the pixel
// centre: the examples' fragments have constant depth and cover the whole
// pixel, so positions do not matter), drawn back to front (the scenes' order:
// green then red; far to near), with enderton's original selection. `exact`
// is the RMS error of ropsim's sampling, derived by enumerating every outcome
// (analysis/enderton_examples_rms.py; docs/results.md); `paper` the value the
// paper prints, asserted within +-0.01 where it agrees with that derivation
// (docs/results.md says why the others differ).
//
// Bound: with D = d^2 in [0, M] (M = 0.49: no channel is off by more than
// 0.7), Var(D) <= M E[D], so the mean of D over N independent pixels is
// within 6 sqrt(M E[D] / N) of E[D] (> 1 - 1e-8), and its square root within
// 6 sqrt(M / N) = 0.0082 of the exact RMS for N = 261632; plus 2e-3 for the
// binary16 targets and colour.
TEST(EndertonExamples, RmsErrorsMatchTheDerivationAndThePaper) {
  struct Row {
    const char* scene;
    Method method;
    std::array<double, 3> exact, paper;
    std::array<bool, 3> paper_agrees;
  };
  const Row rows[] = {
      {"enderton-1", Method::kNaive, {0.2487, 0.2158, 0.2297}, {0.25, 0.21, 0.23}, {true, true, true}},
      {"enderton-1", Method::kEnderton, {0.1000, 0.1548, 0.1580}, {0.10, 0.17, 0.18}, {true, false, false}},
      {"enderton-1", Method::kEndertonAc, {0.1348, 0.1348, 0.0}, {0.17, 0.14, 0.0}, {false, true, true}},
      {"enderton-1", Method::kEndertonDepth, {0.0, 0.0450, 0.1580}, {0.0, 0.05, 0.18}, {true, true, false}},
      {"enderton-1", Method::kEndertonDepthAc, {0.0266, 0.0266, 0.0}, {0.14, 0.12, 0.0}, {false, false, true}},
      {"enderton-2", Method::kNaive, {0.1744, 0.1744, 0.1744}, {0.35, 0.35, 0.35}, {false, false, false}},
      {"enderton-2", Method::kEnderton, {0.1206, 0.1206, 0.1206}, {0.12, 0.12, 0.12}, {true, true, true}},
      {"enderton-2", Method::kEndertonAc, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}, {true, true, true}},
      {"enderton-2", Method::kEndertonDepth, {0.0871, 0.0871, 0.0871}, {0.08, 0.08, 0.08}, {true, true, true}},
      {"enderton-2", Method::kEndertonDepthAc, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}, {true, true, true}},
  };
  for (const auto& r : rows) {
    size_t n = 0;
    const auto got = example_rms(r.scene, r.method, &n);
    ASSERT_GT(n, 260000u) << "too few whole-pixel fragments";
    const double b = 6 * std::sqrt(0.49 / double(n)) + 2e-3 + 1e-4;  // + the derivation's rounding to 4 digits
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(got[size_t(c)], r.exact[size_t(c)], b)
          << r.scene << " " << to_string(r.method) << " channel " << c << ": the derived RMS (bound " << b << ")";
      if (r.paper_agrees[size_t(c)]) {
        EXPECT_NEAR(got[size_t(c)], r.paper[size_t(c)], 0.01)
            << r.scene << " " << to_string(r.method) << " channel " << c << ": the paper's figure";
      }
    }
  }
}

// The original selection differs from the depth-first one where a fragment
// has covered samples that fail the depth test: enderton-1 drawn near to far,
// where green chooses R = floor(0.45 x 4 + xi) of all 4 samples and then
// loses those red holds (original), or floor(0.45 m + xi) of the m samples
// red left (depth-first). Both are unbiased (green's mean 0.45 x 0.55), but
// they choose over different sets, so they write different samples.
TEST(EndertonSelection, OriginalChoosesAmongCoveredSamplesBeforeTheDepthTest) {
  const TraceHeader h = header(128, 128, 4, {0, 0, 1});
  std::vector<Fragment> frags;
  for (uint32_t y = 0; y < 128; ++y)
    for (uint32_t x = 0; x < 128; ++x) {
      frags.push_back(frag(x, y, 0xF, 0.3f, 0.45f, {1, 0, 0}, 0));  // red, near, drawn first
      frags.push_back(frag(x, y, 0xF, 0.6f, 0.45f, {0, 1, 0}, 1));  // green, far
    }
  for (EndertonSelection sel : {EndertonSelection::kDepthFirst, EndertonSelection::kOriginal}) {
    GoldenConfig c;
    c.method = Method::kEnderton;
    c.enderton_selection = sel;
    StochasticModel m(h, c);
    for (const auto& f : frags) m.draw(f);
    const auto mean = mean_pixel(m.resolve());
    const double b = 4 * bound(0.5, 128.0 * 128 * 4) + 1e-3;
    EXPECT_NEAR(mean[1], 0.2475, b) << to_string(sel);
    EXPECT_NEAR(mean[0], 0.45, b) << to_string(sel);
  }
  // The two selections write different samples (the choice is over different sets).
  GoldenConfig a, o;
  a.method = o.method = Method::kEnderton;
  o.enderton_selection = EndertonSelection::kOriginal;
  StochasticModel ma(h, a), mo(h, o);
  for (const auto& f : frags) {
    ma.draw(f);
    mo.draw(f);
  }
  EXPECT_NE(first_state_difference(ma.store(), mo.store()), "") << "the selections chose identically everywhere";
  // Drawn far to near every covered sample survives, so the two are the same.
  StochasticModel fa(h, a), fo(h, o);
  for (size_t i = 0; i < frags.size(); i += 2) {
    for (StochasticModel* m : {&fa, &fo}) {
      m->draw(frags[i + 1]);
      m->draw(frags[i]);
    }
  }
  EXPECT_EQ(first_state_difference(fa.store(), fo.store()), "") << "far to near, both choose among the same samples";
}

// Under `original`, samples_opacity_passed counts the R each fragment chose
// among its covered samples (the opacity decision, as a2c's and hashed's
// count their masks before the depth test), not the chosen that then passed
// the depth test (that is samples_written). enderton-1 drawn near to far:
// green chooses among all 4 samples, some of them held by red. The expected
// sum is enderton_count over the fragments that reach the choice (a fragment
// no sample of which passes leaves at the depth test).
TEST(EndertonSelection, OriginalOpacityCounterIsTheRChosen) {
  const TraceHeader h = header(64, 64, 4, {0, 0, 1});
  std::vector<Fragment> frags;
  for (uint32_t y = 0; y < 64; ++y)
    for (uint32_t x = 0; x < 64; ++x) {
      frags.push_back(frag(x, y, 0xF, 0.3f, 0.45f, {1, 0, 0}, 0));
      frags.push_back(frag(x, y, 0xF, 0.6f, 0.45f, {0, 1, 0}, 1));
    }
  for (EndertonSelection sel : {EndertonSelection::kDepthFirst, EndertonSelection::kOriginal}) {
    GoldenConfig c;
    c.method = Method::kEnderton;
    c.enderton_selection = sel;
    StochasticModel m(h, c);
    uint64_t chosen = 0;
    m.set_counts_observer([&](size_t, const FragWork& w, const Counters&) {
      if (w.killed()) return;
      const uint64_t pool = sel == EndertonSelection::kOriginal ? w.f->coverage : w.survivors;
      chosen += enderton_count(alpha_to_fixed(w.f->alpha, 32), 32, uint32_t(__builtin_popcountll(pool)),
                               fragment_key(c.seed, w.f->draw_id, w.f->prim_id, w.f->x, w.f->y));
    });
    m.draw_batch(frags.data(), frags.size());
    const Counters k = m.counters();
    EXPECT_EQ(k.samples_opacity_passed, chosen) << to_string(sel) << ": the R chosen";
    if (sel == EndertonSelection::kOriginal)
      EXPECT_GT(k.samples_opacity_passed, k.samples_written)
          << "original: some chosen samples fail the depth test, so fewer are written than chosen";
    else
      EXPECT_EQ(k.samples_opacity_passed, k.samples_written) << "depth-first: every chosen sample is written";
  }
}

// A fragment the coverage selection discards (a2c, hashed, hashed-a2c at
// alpha 0) reaches no depth test: it reads no depth and adds no state
// traffic (docs/numerics.md); a fragment it keeps reads the depth of the
// samples kept, 4 bytes each.
TEST(Counters, ADiscardedFragmentReadsNoDepth) {
  const TraceHeader h = header(64, 64, 4);
  std::vector<Fragment> zero, half;
  for (uint32_t y = 0; y < 64; ++y)
    for (uint32_t x = 0; x < 64; ++x) {
      zero.push_back(frag(x, y, 0xF, 0.5f, 0.0f));
      half.push_back(frag(x, y, 0xF, 0.5f, 0.5f, {1, 1, 1}, 0, x + 64 * y));
    }
  for (Method me : {Method::kA2c, Method::kHashed, Method::kHashedA2c}) {
    StochasticModel m = model(h, me);
    m.draw_batch(zero.data(), zero.size());
    const Counters c = m.counters();
    EXPECT_EQ(c.fragments, 64u * 64) << to_string(me);
    EXPECT_EQ(c.samples_tested, 64u * 64 * 4) << to_string(me) << ": the covered samples";
    EXPECT_EQ(c.samples_opacity_passed, 0u) << to_string(me) << ": alpha 0 keeps no sample";
    EXPECT_EQ(c.depth_bytes_read, 0u) << to_string(me) << ": a discarded fragment costs no depth read";
    EXPECT_EQ(c.state_bytes_read(), 0u) << to_string(me);
    EXPECT_EQ(c.state_bytes_written(), 0u) << to_string(me);
    // Alpha 0.5 into the clear buffer: every kept sample passes the depth
    // test, so the depth read is 4 bytes per kept sample.
    StochasticModel m2 = model(h, me);
    m2.draw_batch(half.data(), half.size());
    const Counters c2 = m2.counters();
    EXPECT_GT(c2.samples_opacity_passed, 0u) << to_string(me);
    EXPECT_LT(c2.samples_opacity_passed, c2.samples_tested) << to_string(me) << ": the test needs discarded samples";
    EXPECT_EQ(c2.depth_bytes_read, 4 * c2.samples_opacity_passed) << to_string(me);
  }
}

// ------------------------------------------------------------ vectors from a trace

#include <cstring>
#include <functional>
#include <sstream>

#include "rtl_models/algo/alpha_ref.h"
#include "rtl_models/algo/hilbert.h"
#include "rtl_models/algo/opacity.h"
#include "rtl_models/algo/sort_order.h"
#include "rtl_models/algo/tracker.h"
#include "sim/driver/vectors.h"

namespace {

std::vector<std::string> split_on(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::istringstream in(s);
  for (std::string f; std::getline(in, f, sep);) out.push_back(f);
  if (!s.empty() && s.back() == sep) out.push_back("");
  return out;
}
uint64_t hex_u64(const std::string& s) { return std::stoull(s, nullptr, 16); }
float hex_f32(const std::string& s) {
  const uint32_t b = uint32_t(std::stoul(s, nullptr, 16));
  float f;
  std::memcpy(&f, &b, 4);
  return f;
}

/// The rows (header dropped, each split at commas) of unit's vectors from req.
struct Captured {
  std::string text;
  uint64_t returned = 0;
  std::vector<std::vector<std::string>> rows;
};
Captured capture(const std::string& unit, const TraceVectorRequest& req) {
  Captured c;
  c.returned = make_trace_vectors(unit, req, [&c](std::string_view s) { c.text += s; });
  const auto lines = split_on(c.text, '\n');
  for (size_t i = 1; i < lines.size(); ++i)
    if (!lines[i].empty()) c.rows.push_back(split_on(lines[i], ','));
  return c;
}

/// The calls of each unit the replay of in with cfg makes, counted from the
/// golden model's counters: every fragment's counter delta (every pass),
/// for the fragments keep() accepts.
struct Calls {
  uint64_t depth_tests = 0;     ///< fragments charged a depth read (4 bytes per tested sample)
  uint64_t depth_samples = 0;   ///< depth_bytes_read / 4
  uint64_t tracked = 0;         ///< fragments whose tracker was written
  uint64_t multi_sorts = 0;     ///< sorts
  uint64_t survivors = 0;       ///< samples_depth_passed of the fragments that reach the tracker / the write
  uint64_t opacity_passed = 0;  ///< samples_opacity_passed
};
Calls count_calls(const InputSpec& in, const GoldenConfig& cfg, const std::function<bool(const Fragment&)>& keep) {
  const FragmentList list = load_fragments(in);
  StochasticModel m(list.header, cfg);
  Calls c;
  m.set_counts_observer([&](size_t, const FragWork& w, const Counters& d) {
    if (!keep(*w.f)) return;
    c.depth_tests += d.depth_bytes_read > 0;
    c.depth_samples += d.depth_bytes_read / 4;
    c.tracked += d.tracker_bytes_written > 0;
    c.multi_sorts += d.sorts;
    c.survivors += d.samples_depth_passed;
    c.opacity_passed += d.samples_opacity_passed;
  });
  for (int p = 0; p < m.passes(); ++p) {
    m.begin_pass(p);
    m.draw_batch(list.fragments.data(), list.fragments.size());
  }
  return c;
}

/// Checks every row of unit against the unit's own function (rtl_models/algo)
/// applied to the row's inputs; counts in *interesting the rows with a
/// property worth seeing (a new surface, two or more to sort, a pass), so a
/// test can ask for variety.
void check_rows(const std::string& unit, const Captured& c, const std::string& what, uint64_t* interesting_out) {
  uint64_t& interesting = *interesting_out;
  interesting = 0;
  for (size_t r = 0; r < c.rows.size(); ++r) {
    const auto& v = c.rows[r];
    const std::string at = what + " " + unit + " row " + std::to_string(r + 1);
    if (unit == "depth-test") {
      ASSERT_EQ(v.size(), 8u) << at;
      const int spp = std::stoi(v[0]);
      const uint64_t cov = hex_u64(v[1]);
      const float z0 = hex_f32(v[2]), dzdx = hex_f32(v[3]), dzdy = hex_f32(v[4]);
      const auto stored = split_on(v[5], ';'), zs = split_on(v[6], ';');
      EXPECT_NE(cov, 0u) << at << ": a depth test with nothing to test";
      const auto pos = standard_sample_positions(spp);
      uint64_t pass = 0;
      for (int i = 0; i < spp; ++i) {
        if (!(cov >> i & 1)) {
          EXPECT_EQ(zs[size_t(i)], "-") << at;
          continue;
        }
        const float z = plane_depth(z0, dzdx, dzdy, sample_offset(pos[size_t(i)].x), sample_offset(pos[size_t(i)].y));
        EXPECT_EQ(depth_bits(z), uint32_t(hex_u64(zs[size_t(i)]))) << at << ": sample " << i << "'s depth";
        if (depth_passes(z, hex_f32(stored[size_t(i)]))) pass |= uint64_t{1} << i;
      }
      EXPECT_EQ(pass, hex_u64(v[7])) << at << ": the samples that pass";
      interesting += pass != cov;
    } else if (unit == "tracker") {
      ASSERT_EQ(v.size(), 9u) << at;
      TrackerState t{hex_u64(v[2]), uint32_t(std::stoul(v[3]))};
      const uint64_t surviving = hex_u64(v[4]);
      const TrackResult res = track_surface(t, surviving, std::stoi(v[1]));
      track_commit(t, surviving);
      EXPECT_EQ(int(res.new_surface), std::stoi(v[5])) << at;
      EXPECT_EQ(res.n, uint32_t(std::stoul(v[6]))) << at;
      EXPECT_EQ(t.surface_id, uint32_t(std::stoul(v[7]))) << at;
      EXPECT_EQ(t.covered, hex_u64(v[8])) << at;
      interesting += res.new_surface;
    } else if (unit == "sorter") {
      ASSERT_EQ(v.size(), 4u) << at;
      const int spp = std::stoi(v[0]);
      const auto stored_s = split_on(v[2], ';');
      float stored[64];
      for (int i = 0; i < spp; ++i) stored[i] = hex_f32(stored_s[size_t(i)]);
      uint8_t order[64];
      const int m = sort_by_stored_depth(stored, hex_u64(v[1]), order);
      std::string want;
      for (int k = 0; k < m; ++k) want += (k ? ";" : "") + std::to_string(order[k]);
      EXPECT_EQ(v[3], want) << at;
      interesting += m > 1;
    } else if (unit == "alpha-ref") {
      ASSERT_EQ(v.size(), 7u) << at;
      const uint32_t s = uint32_t(std::stoul(v[0])), sid = uint32_t(std::stoul(v[2])), spp = uint32_t(std::stoul(v[3]));
      const uint64_t p = std::stoull(v[1]);
      const int hb = std::stoi(v[4]);
      const uint32_t idx = alpha_ref_index(s, p, spp, hb);
      EXPECT_EQ(idx, uint32_t(hex_u64(v[5]))) << at;
      EXPECT_EQ(calc_alpha_ref_index(idx, sid, hb), uint32_t(hex_u64(v[6]))) << at;
      interesting += sid > 0;
    } else if (unit == "opacity") {
      ASSERT_EQ(v.size(), 5u) << at;
      const bool pass = opacity_passes(hex_u64(v[2]), std::stoi(v[0]), uint32_t(hex_u64(v[3])), std::stoi(v[1]));
      EXPECT_EQ(int(pass), std::stoi(v[4])) << at;
      interesting += pass;
    } else if (unit == "hilbert") {
      ASSERT_EQ(v.size(), 4u) << at;
      const int order = std::stoi(v[0]);
      EXPECT_EQ(hilbert_xy2d(1u << order, uint32_t(std::stoul(v[1])), uint32_t(std::stoul(v[2]))), hex_u64(v[3])) << at;
      interesting += 1;
    }
  }
}

uint64_t expect_rows_are_the_unit_function(const std::string& unit, const Captured& c, const std::string& what) {
  uint64_t interesting = 0;
  check_rows(unit, c, what, &interesting);
  return interesting;
}

}  // namespace

// Vectors from a trace: every row's outputs are the unit's function of the
// row's inputs, and there is one row per call the replay makes, counted
// independently from the golden model's counters (per-fragment deltas):
// lk's depth tests (4 bytes of depth per tested sample), tracker updates
// (its tracker writes), sorts (the `sorts` counter: rows with two or more
// survivors), references and opacity tests (one per surviving sample; the
// passes are samples_opacity_passed) and Hilbert indices (one per fragment
// that reaches the references). Then a window, a draw id, a second pass,
// a coverage selection that discards fragments, naive's opacity tests, and
// the hex format.
TEST(TraceVectors, EveryRowIsTheUnitFunctionAndEveryCallIsARow) {
  auto all = [](const Fragment&) { return true; };
  TraceVectorRequest req;
  req.input.scene.name = "cloth";
  req.input.scene.spp = 4;
  req.input.scene.width = req.input.scene.height = 64;
  req.method.method = Method::kLk;
  const Calls lk = count_calls(req.input, req.method, all);
  ASSERT_GT(lk.tracked, 100u) << "the test needs content";
  struct Want {
    const char* unit;
    uint64_t rows, interesting_at_least;
  };
  for (const Want& u : {Want{"depth-test", lk.depth_tests, 1}, Want{"tracker", lk.tracked, 1},
                        Want{"sorter", lk.tracked, lk.multi_sorts}, Want{"alpha-ref", lk.survivors, 1},
                        Want{"opacity", lk.survivors, lk.opacity_passed}, Want{"hilbert", lk.tracked, lk.tracked}}) {
    const Captured c = capture(u.unit, req);
    EXPECT_EQ(c.rows.size(), u.rows) << u.unit << ": one row per call";
    EXPECT_EQ(c.returned, c.rows.size()) << u.unit;
    const uint64_t interesting = expect_rows_are_the_unit_function(u.unit, c, "cloth lk");
    EXPECT_GE(interesting, u.interesting_at_least) << u.unit << ": the rows lack variety";
    if (std::string(u.unit) == "sorter") {
      EXPECT_EQ(interesting, lk.multi_sorts) << "rows with 2+ survivors: sorts";
    }
    if (std::string(u.unit) == "opacity") {
      EXPECT_EQ(interesting, lk.opacity_passed) << "passing rows";
    }
  }
  // The depth test's samples are the counters' 4 bytes each.
  {
    const Captured c = capture("depth-test", req);
    uint64_t samples = 0;
    for (const auto& v : c.rows) samples += uint64_t(__builtin_popcountll(hex_u64(v[1])));
    EXPECT_EQ(samples, lk.depth_samples);
  }
  // A window: only its pixels' calls.
  {
    TraceVectorRequest w = req;
    w.window = TraceVectorRequest::Window{16, 20, 31, 40};
    const Calls in_w = count_calls(w.input, w.method,
                                   [](const Fragment& f) { return f.x >= 16 && f.x <= 31 && f.y >= 20 && f.y <= 40; });
    ASSERT_GT(in_w.tracked, 0u);
    ASSERT_LT(in_w.tracked, lk.tracked);
    EXPECT_EQ(capture("tracker", w).rows.size(), in_w.tracked);
    EXPECT_EQ(capture("alpha-ref", w).rows.size(), in_w.survivors);
  }
  // A draw id (eight-layers: one draw per surface), and lk+ac's two passes,
  // each of which depth-tests every fragment.
  {
    TraceVectorRequest d;
    d.input.scene.name = "eight-layers";
    d.input.scene.spp = 4;
    d.input.scene.width = d.input.scene.height = 32;
    d.method.method = Method::kLk;
    d.draw = 3;
    const Calls c3 = count_calls(d.input, d.method, [](const Fragment& f) { return f.draw_id == 3; });
    ASSERT_GT(c3.depth_tests, 0u);
    const Captured dt = capture("depth-test", d);
    EXPECT_EQ(dt.rows.size(), c3.depth_tests);
    expect_rows_are_the_unit_function("depth-test", dt, "eight-layers draw 3");
    d.method.method = Method::kLkAc;
    d.draw.reset();
    const Calls ac = count_calls(d.input, d.method, all);
    const Captured two = capture("depth-test", d);
    EXPECT_EQ(two.rows.size(), ac.depth_tests);
    EXPECT_EQ(two.rows.size(), 2 * load_fragments(d.input).fragments.size()) << "every fragment, in both passes";
    expect_rows_are_the_unit_function("depth-test", two, "eight-layers lk+ac");
  }
  // hashed-a2c on the foliage: a fragment its mask discards reaches no
  // depth test, so there are fewer rows than fragments.
  {
    TraceVectorRequest h;
    h.input.scene.name = "foliage";
    h.input.scene.spp = 4;
    h.input.scene.width = h.input.scene.height = 64;
    h.method.method = Method::kHashedA2c;
    const Calls hc = count_calls(h.input, h.method, all);
    const Captured dt = capture("depth-test", h);
    EXPECT_EQ(dt.rows.size(), hc.depth_tests);
    EXPECT_LT(dt.rows.size(), load_fragments(h.input).fragments.size()) << "the foliage has discarded fragments";
    expect_rows_are_the_unit_function("depth-test", dt, "foliage hashed-a2c");
    // naive: one opacity test per surviving sample, against its 32-bit random reference.
    h.method.method = Method::kNaive;
    const Calls nc = count_calls(h.input, h.method, all);
    const Captured op = capture("opacity", h);
    EXPECT_EQ(op.rows.size(), nc.survivors);
    EXPECT_EQ(expect_rows_are_the_unit_function("opacity", op, "foliage naive"), nc.opacity_passed);
  }
  // The hex format: the same rows, one word each.
  {
    TraceVectorRequest x = req;
    x.format = "hex";
    const Captured c = capture("tracker", x);
    uint64_t words = 0;
    for (const auto& line : split_on(c.text, '\n')) words += !line.empty() && line.rfind("//", 0) != 0;
    EXPECT_EQ(words, lk.tracked);
    EXPECT_EQ(c.returned, lk.tracked);
  }
  // A method that never calls the unit, and a unit --trace cannot capture.
  TraceVectorRequest e = req;
  e.method.method = Method::kEnderton;
  EXPECT_THROW(make_trace_vectors("tracker", e, [](std::string_view) {}), VectorError);
  EXPECT_THROW(make_trace_vectors("half", req, [](std::string_view) {}), VectorError);
  e.method.method = Method::kSlab;
  EXPECT_THROW(make_trace_vectors("depth-test", e, [](std::string_view) {}), VectorError);
  // blend tests depth with each draw's function, not the unit's LESS_EQUAL.
  e.method.method = Method::kBlend;
  EXPECT_THROW(make_trace_vectors("depth-test", e, [](std::string_view) {}), VectorError);
}
