// Every method on a frame of draw states (docs/methods.md "Methods on a frame
// of draw states"): opaque draws are a z-buffer's writes with their own depth
// state, additive and other blends are applied to the colour as `blend`
// applies them, src-over draws (premultiplied ones un-premultiplied) are the
// method's; the reference composites the src-over fragments over the colour
// buffer of the rest. Each test states what it checks against.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "rtl_models/functional/composite.h"
#include "rtl_models/functional/compressibility.h"
#include "rtl_models/functional/framebuffer_blend.h"
#include "rtl_models/golden/golden_model.h"
#include "sim/image/image_io.h"
#include "traces/raster/sample_patterns.h"

using namespace ropsim;

namespace {

TraceHeader header(uint32_t w, uint32_t h, int spp, std::vector<DrawState> draws) {
  TraceHeader hd;
  hd.width = w;
  hd.height = h;
  hd.spp = spp;
  hd.positions = standard_sample_positions(spp);
  hd.clear_color = {0.2f, 0.3f, 0.4f};
  hd.draws = DrawTable(std::move(draws));
  return hd;
}

uint64_t all_samples(int spp) { return spp == 64 ? ~0ull : (1ull << spp) - 1; }

Fragment frag(uint32_t draw, uint32_t x, uint32_t y, float z, std::array<float, 4> rgba, uint64_t coverage) {
  Fragment f;
  f.draw_id = draw;
  f.x = uint16_t(x);
  f.y = uint16_t(y);
  f.coverage = coverage;
  f.z0 = z;
  f.rgb = {rgba[0], rgba[1], rgba[2]};
  f.alpha = rgba[3];
  return f;
}

/// A rectangle of fragments [x0, x1) x [y0, y1) of one draw, every sample covered.
void rect(std::vector<Fragment>& out, uint32_t draw, uint32_t x0, uint32_t y0, uint32_t x1, uint32_t y1, float z,
          std::array<float, 4> rgba, int spp) {
  for (uint32_t y = y0; y < y1; ++y)
    for (uint32_t x = x0; x < x1; ++x) out.push_back(frag(draw, x, y, z, rgba, all_samples(spp)));
}

DrawState opaque_draw(uint32_t id, TargetEncoding e, DepthFunc f = DepthFunc::kLess, bool write = true) {
  DrawState s = default_draw_state(id);
  s.blend = false;
  s.depth_test = true;
  s.depth_func = f;
  s.depth_write = write;
  s.encoding = e;
  return s;
}

DrawState blended_draw(uint32_t id, TargetEncoding e, BlendFactor src, BlendFactor dst) {
  DrawState s = default_draw_state(id);
  s.src_rgb = s.src_alpha = src;
  s.dst_rgb = s.dst_alpha = dst;
  s.depth_func = DepthFunc::kLequal;
  s.encoding = e;
  return s;
}

DrawState src_over(uint32_t id, TargetEncoding e, bool premultiplied = false) {
  DrawState s = default_draw_state(id);
  if (premultiplied) s.src_rgb = BlendFactor::kOne;
  s.encoding = e;
  return s;
}

GoldenConfig config(Method m) {
  GoldenConfig c;
  c.method = m;
  return c;
}

std::unique_ptr<FunctionalModel> run(const TraceHeader& h, const std::vector<Fragment>& frags, Method m) {
  auto model = make_functional_model(h, config(m), 1);
  for (int p = 0; p < model->passes(); ++p) {
    model->begin_pass(p);
    for (const Fragment& f : frags) model->draw(f);
  }
  return model;
}

/// The methods with per-sample colour and one pass: they run every draw kind.
const std::vector<Method> kSinglePass = {Method::kLk,     Method::kEnderton,  Method::kNaive, Method::kA2c,
                                         Method::kHashed, Method::kHashedA2c, Method::kOpaque};

/// An 8 x 8 unorm8 frame of opaque draws with several depth states, an
/// additive and a multiplying draw: no src-over draw.
std::vector<Fragment> opaque_frame(TraceHeader& h, int spp) {
  const TargetEncoding e = TargetEncoding::kUnorm8;
  h = header(8, 8, spp,
             {opaque_draw(0, e), opaque_draw(1, e), opaque_draw(2, e, DepthFunc::kAlways, false),
              blended_draw(3, e, BlendFactor::kOne, BlendFactor::kOne),
              blended_draw(4, e, BlendFactor::kDstColor, BlendFactor::kZero), opaque_draw(5, e, DepthFunc::kGequal)});
  std::vector<Fragment> f;
  rect(f, 0, 0, 0, 8, 8, 0.6f, {0.8f, 0.1f, 0.1f, 0.3f}, spp);     // background
  rect(f, 1, 2, 2, 6, 6, 0.3f, {0.1f, 0.7f, 0.2f, 0.5f}, spp);     // nearer: wins
  rect(f, 1, 0, 0, 3, 3, 0.9f, {1.0f, 1.0f, 1.0f, 1.0f}, spp);     // farther: hidden
  rect(f, 2, 6, 0, 8, 8, 0.95f, {0.9f, 0.9f, 0.0f, 1.0f}, spp);    // depth test ALWAYS, no write: on top
  rect(f, 3, 1, 1, 7, 4, 0.2f, {0.25f, 0.125f, 0.5f, 0.4f}, spp);  // additive
  rect(f, 4, 3, 3, 8, 8, 0.1f, {0.5f, 1.0f, 0.75f, 1.0f}, spp);    // multiply
  rect(f, 5, 0, 6, 4, 8, 0.7f, {0.0f, 0.3f, 0.9f, 1.0f}, spp);     // GEQUAL: the farther wins
  return f;
}

void expect_same_image(const Image& a, const Image& b, const std::string& what) {
  ASSERT_EQ(a.width, b.width);
  int differ = 0;
  for (uint32_t y = 0; y < a.height; ++y)
    for (uint32_t x = 0; x < a.width; ++x)
      for (int c = 0; c < 3; ++c)
        if (a.at(x, y)[c] != b.at(x, y)[c] && ++differ <= 3)
          ADD_FAILURE() << what << ": pixel (" << x << ", " << y << ") channel " << c << ": " << a.at(x, y)[c]
                        << " vs blend's " << b.at(x, y)[c];
  EXPECT_EQ(differ, 0) << what;
}

}  // namespace

TEST(DrawRoutes, AFrameWithoutSrcOverDrawsIsBlendsFrameForEveryMethod) {
  // Without src-over draws nothing is order-dependent transparency: every
  // method (and the A-buffer reference) must produce blend's frame exactly:
  // the same 8-bit codes, decoded the same way.
  for (int spp : {1, 4, 16}) {
    TraceHeader h;
    const std::vector<Fragment> f = opaque_frame(h, spp);
    const Image want = run(h, f, Method::kBlend)->resolve();
    std::vector<Method> methods = kSinglePass;
    methods.push_back(Method::kReference);
    for (Method m : methods)
      expect_same_image(run(h, f, m)->resolve(), want,
                        std::string(to_string(m)) + " at " + std::to_string(spp) + " spp");
  }
}

TEST(DrawRoutes, OpaqueAndBlendedDrawsCostLkWhatTheyCostAZBuffer) {
  // lk's opaque and blended draws bypass the tracker, the sorter and the
  // reference generator: every counter equals the plain z-buffer's (the
  // opaque method) on the same frame.
  TraceHeader h;
  const std::vector<Fragment> f = opaque_frame(h, 16);
  const Counters lk = run(h, f, Method::kLk)->counters(), zb = run(h, f, Method::kOpaque)->counters();
  std::vector<uint64_t> a, b;
  lk.for_each([&](const char*, uint64_t v) { a.push_back(v); });
  zb.for_each([&](const char*, uint64_t v) { b.push_back(v); });
  EXPECT_EQ(a, b) << "lk's counters on a frame without src-over draws differ from a z-buffer's";
  EXPECT_EQ(lk.tracker_bytes_read, 0u);
  EXPECT_EQ(lk.sorts, 0u);
  // The blended draws read the colour they blend into, the opaque ones do not:
  // 4 bytes per blended sample of the unorm8 target (draws 3 and 4: 18 and 25
  // fragments, 16 spp, each wholly visible in front of the opaque draws).
  EXPECT_EQ(lk.samples_blended, (18u + 25u) * 16u);
  EXPECT_EQ(lk.target_bytes_read, (18u + 25u) * 16u * kRgba8SampleBytes);
}

TEST(DrawRoutes, FragmentsAreCountedByTheirDrawsKind) {
  TraceHeader h;
  std::vector<Fragment> f = opaque_frame(h, 4);
  std::vector<DrawState> draws = h.draws.states();
  draws.push_back(src_over(6, TargetEncoding::kUnorm8));
  draws.push_back(src_over(7, TargetEncoding::kUnorm8, true));
  h.draws = DrawTable(draws);
  rect(f, 6, 0, 0, 2, 1, 0.05f, {1, 0, 0, 0.5f}, 4);
  rect(f, 7, 0, 0, 3, 1, 0.05f, {0.5f, 0, 0, 0.5f}, 4);
  // Opaque: draws 0, 1, 2, 5 (64 + 16 + 9 + 16 + 8); additive: 18; other: 25.
  const DrawKindCounts want = {113, 2, 3, 18, 25};
  for (Method m : {Method::kLk, Method::kBlend, Method::kReference})
    EXPECT_EQ(run(h, f, m)->kind_fragments(), want) << to_string(m);
}

TEST(DrawRoutes, SrcOverOverAnOpaqueDrawMatchesTheReference) {
  // An opaque draw, then a src-over draw at alpha 1/2 in front of it and one
  // behind it. lk's stratification keeps exactly half of each pixel's 16
  // samples, so its image is the over composite (the reference's) to the
  // binary16 rounding of the colour buffer; the draw behind is hidden in both.
  const TargetEncoding e = TargetEncoding::kFloat;
  const TraceHeader h = header(4, 4, 16, {opaque_draw(0, e), src_over(1, e), src_over(2, e)});
  std::vector<Fragment> f;
  rect(f, 0, 0, 0, 4, 4, 0.5f, {0.2f, 0.4f, 0.8f, 0.25f}, 16);  // the opaque draw's alpha is ignored: it is 1
  rect(f, 1, 0, 0, 4, 4, 0.3f, {1.0f, 0.5f, 0.0f, 0.5f}, 16);
  rect(f, 2, 0, 0, 4, 4, 0.7f, {0.0f, 1.0f, 1.0f, 0.5f}, 16);  // behind the opaque draw
  const Image ref = run(h, f, Method::kReference)->resolve(), lk = run(h, f, Method::kLk)->resolve();
  const float want[3] = {0.5f * 1.0f + 0.5f * 0.2f, 0.5f * 0.5f + 0.5f * 0.4f, 0.5f * 0.8f};
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(ref.at(1, 1)[c], want[c], 1e-3) << "reference channel " << c;
    EXPECT_NEAR(lk.at(1, 1)[c], want[c], 1e-3) << "lk channel " << c;
  }
}

TEST(DrawRoutes, PremultipliedSrcOverIsSrcOverOfTheStraightColour) {
  // ONE, ONE_MINUS_SRC_ALPHA with colour c a is src-over of colour c: every
  // method sees the straight colour, to float rounding of c a / a.
  const TargetEncoding e = TargetEncoding::kFloat;
  for (Method m : {Method::kLk, Method::kWboit, Method::kReference, Method::kBlend}) {
    Image img[2];
    for (int premultiplied = 0; premultiplied < 2; ++premultiplied) {
      const TraceHeader h = header(2, 2, 8, {src_over(0, e, premultiplied)});
      const float a = 0.375f;
      const std::array<float, 4> c = premultiplied ? std::array<float, 4>{0.9f * a, 0.6f * a, 0.3f * a, a}
                                                   : std::array<float, 4>{0.9f, 0.6f, 0.3f, a};
      std::vector<Fragment> f;
      rect(f, 0, 0, 0, 2, 2, 0.5f, c, 8);
      img[premultiplied] = run(h, f, m)->resolve();
    }
    for (int ch = 0; ch < 3; ++ch)
      EXPECT_NEAR(img[1].at(0, 0)[ch], img[0].at(0, 0)[ch], 1e-5) << to_string(m) << " channel " << ch;
  }
}

TEST(DrawRoutes, AnAdditiveDrawIsAddedWhereverItPassesTheDepthTest) {
  // Additive particles over an opaque draw, half of them behind it: lk adds
  // them where they are in front, exactly as blend does (a float target:
  // to binary16 rounding), and nowhere else.
  const TargetEncoding e = TargetEncoding::kFloat;
  const TraceHeader h =
      header(4, 1, 4, {opaque_draw(0, e), blended_draw(1, e, BlendFactor::kSrcAlpha, BlendFactor::kOne)});
  std::vector<Fragment> f;
  rect(f, 0, 0, 0, 4, 1, 0.5f, {0.25f, 0.25f, 0.25f, 1}, 4);
  rect(f, 1, 0, 0, 2, 1, 0.4f, {0.5f, 0.25f, 1.0f, 0.5f}, 4);  // in front
  rect(f, 1, 2, 0, 4, 1, 0.6f, {0.5f, 0.25f, 1.0f, 0.5f}, 4);  // behind
  const Image lk = run(h, f, Method::kLk)->resolve(), bl = run(h, f, Method::kBlend)->resolve();
  const float front[3] = {0.25f + 0.25f, 0.25f + 0.125f, 0.25f + 0.5f};
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(bl.at(0, 0)[c], front[c], 1e-6) << "blend, in front, channel " << c;
    EXPECT_NEAR(lk.at(0, 0)[c], front[c], 1e-3) << "lk, in front, channel " << c;
    EXPECT_NEAR(lk.at(3, 0)[c], 0.25f, 1e-3) << "lk, behind, channel " << c;
  }
}

/// The methods that composite over a background (or slab its layers) and
/// run a frame of draw states with a pre-pass of its opaque and blended draws.
const std::vector<Method> kPrepass = {Method::kWboit,      Method::kSlab,           Method::kLkAc,
                                      Method::kEndertonAc, Method::kLkDepth,        Method::kEndertonDepth,
                                      Method::kLkDepthAc,  Method::kEndertonDepthAc};

TEST(DrawRoutes, ThePrepassMethodsRunAFramesOpaqueAndBlendedDrawsFirst) {
  // The passes: the pre-pass only on a frame with opaque or blended draws,
  // and only for the methods that composite over a background.
  const TargetEncoding e = TargetEncoding::kUnorm8;
  const TraceHeader mixed = header(2, 2, 4, {src_over(0, e), opaque_draw(1, e)});
  const TraceHeader clear = header(2, 2, 4, {src_over(0, e), src_over(1, e, true)});
  for (Method m : kPrepass) {
    const PassList p = run_passes(mixed, m), own = passes_of(m);
    ASSERT_EQ(p.count, own.count + 1) << to_string(m);
    EXPECT_EQ(p.pass[0], PassKind::kPrepass) << to_string(m);
    for (int i = 0; i < own.count; ++i) EXPECT_EQ(p.pass[i + 1], own.pass[i]) << to_string(m);
    EXPECT_EQ(run_passes(clear, m).count, own.count) << to_string(m) << ": no pre-pass without opaque draws";
  }
  for (Method m : {Method::kLk, Method::kBlend, Method::kOpaque})
    EXPECT_EQ(run_passes(mixed, m).count, 1) << to_string(m) << " routes the draws in its one pass";
}

TEST(DrawRoutes, AFrameWithoutSrcOverDrawsIsThePrepassMethodsBackground) {
  // Without src-over draws, every pre-pass method shows the pre-pass's
  // colour buffer: blend's frame. The composites store each sample's value
  // as the target stores it and resolve as blend does, so wboit's, +ac's,
  // +depth's and +depth+ac's PNG is blend's byte for byte; slab resolves its
  // layers' working values, to half a code.
  for (int spp : {1, 4, 16}) {
    TraceHeader h;
    const std::vector<Fragment> f = opaque_frame(h, spp);
    const Image want = run(h, f, Method::kBlend)->resolve();
    for (Method m : kPrepass) {
      const Image got = run(h, f, m)->resolve();
      if (m != Method::kSlab) {
        expect_same_image(got, want, std::string(to_string(m)) + " at " + std::to_string(spp) + " spp");
        continue;
      }
      double worst = 0;
      for (uint32_t y = 0; y < want.height; ++y)
        for (uint32_t x = 0; x < want.width; ++x)
          for (int c = 0; c < 3; ++c)
            worst = std::max(worst, std::abs(255.0 * double(linear_to_srgb(got.at(x, y)[c])) -
                                             255.0 * double(linear_to_srgb(want.at(x, y)[c]))));
      EXPECT_LE(worst, 0.5 + 1e-3) << to_string(m) << " at " << spp << " spp: codes off blend's";
    }
  }
}

TEST(DrawRoutes, ThePrepassMethodsCompositeSrcOverOverTheOpaqueDraws) {
  // An opaque draw, a src-over draw at alpha 1/2 in front of it and one
  // behind it (float target): one layer in front, so every pre-pass method's
  // estimate is exact, the over composite (the reference's), to binary16
  // rounding (1e-3): +ac's A = 1/2 exactly whichever samples its stochastic
  // pass writes, and at alpha 1/2 and 16 spp lk and enderton write R = 8,
  // so +depth's (S - R) / S is 1/2 too; the draw behind is hidden. And the
  // opaque draw costs them what it costs a z-buffer: its fragments' depth
  // and colour written once (+ac's stochastic colour goes to its
  // accumulation target, not the colour buffer).
  const TargetEncoding e = TargetEncoding::kFloat;
  const TraceHeader h = header(4, 4, 16, {opaque_draw(0, e), src_over(1, e), src_over(2, e)});
  std::vector<Fragment> f;
  rect(f, 0, 0, 0, 4, 4, 0.5f, {0.2f, 0.4f, 0.8f, 0.25f}, 16);
  rect(f, 1, 0, 0, 4, 4, 0.3f, {1.0f, 0.5f, 0.0f, 0.5f}, 16);
  rect(f, 2, 0, 0, 4, 4, 0.7f, {0.0f, 1.0f, 1.0f, 0.5f}, 16);  // behind the opaque draw
  const float want[3] = {0.5f * 1.0f + 0.5f * 0.2f, 0.5f * 0.5f + 0.5f * 0.4f, 0.5f * 0.8f};
  const Image ref = run(h, f, Method::kReference)->resolve();
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(ref.at(1, 1)[c], want[c], 1e-3) << "reference channel " << c;
  for (Method m : kPrepass) {
    auto model = run(h, f, m);
    const Image img = model->resolve();
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(img.at(1, 1)[c], want[c], 1e-3) << to_string(m) << " channel " << c;
    // Every pass reads the whole trace; the src-over draws are tested in the
    // method's passes only, the opaque draw in the pre-pass only.
    const Counters c = model->counters();
    const uint64_t passes = uint64_t(run_passes(h, m).count);
    EXPECT_EQ(c.fragments, passes * 48u) << to_string(m);
    EXPECT_EQ(c.color_bytes_written, 16u * 16u * kColorSampleBytes) << to_string(m) << ": the opaque draw's colour";
    EXPECT_EQ(model->kind_fragments()[size_t(DrawKind::kOpaque)], 16u) << to_string(m) << ": counted once";
  }
}

TEST(DrawRoutes, ASrcOverDrawWithItsDepthTestOffIsNeverHidden) {
  // A HUD: an opaque draw near the eye, then a src-over draw at alpha 1
  // behind it with its depth test off. Every method shows the HUD, as blend
  // does; with its depth test on, every method hides it.
  const TargetEncoding e = TargetEncoding::kFloat;
  for (bool test : {false, true}) {
    DrawState hud = src_over(1, e);
    hud.depth_test = test;
    const TraceHeader h = header(4, 4, 16, {opaque_draw(0, e), hud});
    std::vector<Fragment> f;
    rect(f, 0, 0, 0, 4, 4, 0.3f, {0.2f, 0.4f, 0.8f, 1.0f}, 16);
    rect(f, 1, 0, 0, 4, 4, 0.9f, {1.0f, 0.5f, 0.0f, 1.0f}, 16);
    const std::array<float, 3> want =
        test ? std::array<float, 3>{0.2f, 0.4f, 0.8f} : std::array<float, 3>{1.0f, 0.5f, 0.0f};
    std::vector<Method> methods = kSinglePass;
    methods.insert(methods.end(), kPrepass.begin(), kPrepass.end());
    methods.push_back(Method::kReference);
    methods.push_back(Method::kBlend);
    for (Method m : methods) {
      const Image img = run(h, f, m)->resolve();
      for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(img.at(2, 2)[c], want[size_t(c)], 1e-3)
            << to_string(m) << " channel " << c
            << (test ? ": the depth-tested draw behind shows" : ": the HUD is hidden");
    }
  }
}

TEST(DrawRoutes, AnOpaqueDrawAfterASrcOverDrawWithItsDepthTestOffHidesIt) {
  // A sky: a src-over draw at alpha 1 near the eye with its depth test off,
  // drawn first; then an opaque draw behind it over the left half. The
  // opaque draw replaces the sky where it covers (as blend does), and the sky
  // shows elsewhere: in every method and in the A-buffer reference, which
  // hides a fragment that tests no depth where an opaque one drawn after it
  // wrote the sample.
  const TargetEncoding e = TargetEncoding::kFloat;
  DrawState sky = src_over(0, e);
  sky.depth_test = false;
  const TraceHeader h = header(4, 2, 16, {sky, opaque_draw(1, e)});
  std::vector<Fragment> f;
  rect(f, 0, 0, 0, 4, 2, 0.1f, {0.3f, 0.6f, 0.9f, 1.0f}, 16);
  rect(f, 1, 0, 0, 2, 2, 0.9f, {0.8f, 0.2f, 0.1f, 1.0f}, 16);
  std::vector<Method> methods = kSinglePass;
  methods.push_back(Method::kReference);
  methods.push_back(Method::kBlend);
  const std::array<float, 3> opaque = {0.8f, 0.2f, 0.1f}, sky_colour = {0.3f, 0.6f, 0.9f};
  for (Method m : methods) {
    const Image img = run(h, f, m)->resolve();
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(img.at(1, 1)[c], opaque[size_t(c)], 1e-3)
          << to_string(m) << " channel " << c << ": the opaque draw after the sky replaces it";
      EXPECT_NEAR(img.at(3, 1)[c], sky_colour[size_t(c)], 1e-3)
          << to_string(m) << " channel " << c << ": the sky shows where nothing is drawn after it";
    }
  }
}

TEST(DrawRoutes, OverAPrepassAcAndDepthMarkTheirWrittenSamplesOutsideTheDepthBuffer) {
  // Over a pre-pass the depth buffer holds the opaque draw's depth, which
  // the stochastic pass overwrites: +ac writes its colour as (c, 1) into
  // the accumulation target and leaves the colour buffer the background;
  // +depth writes 0 into the transmittance target. Each marks exactly the
  // samples whose depth the stochastic pass wrote (the src-over draw's, in
  // front), and a frame of src-over draws keeps the targets without them.
  const TargetEncoding e = TargetEncoding::kFloat;
  const TraceHeader h = header(2, 2, 16, {opaque_draw(0, e), src_over(1, e)});
  std::vector<Fragment> f;
  rect(f, 0, 0, 0, 2, 2, 0.5f, {0.2f, 0.4f, 0.8f, 1.0f}, 16);
  rect(f, 1, 0, 0, 2, 2, 0.3f, {1.0f, 0.5f, 0.0f, 0.5f}, 16);
  const float z_back = canonical_depth(0.5f);
  for (Method m : {Method::kLkAc, Method::kEndertonAc, Method::kLkDepth, Method::kEndertonDepth}) {
    const bool ac = traits(m).total_alpha;
    auto model = run(h, f, m);
    const auto* golden = dynamic_cast<const StochasticModel*>(model.get());
    ASSERT_NE(golden, nullptr);
    const BlendFormats fmt = golden->store().targets().formats;
    int written = 0;
    for (uint32_t y = 0; y < 2; ++y)
      for (uint32_t x = 0; x < 2; ++x) {
        const PixelView v = golden->pixel_view(x, y);
        ASSERT_TRUE(ac ? v.accum != nullptr : v.trans != nullptr) << to_string(m);
        for (int s = 0; s < 16; ++s) {
          const bool w = v.depth[s] != z_back;  // the stochastic pass's depth
          written += w;
          for (int c = 0; c < 3; ++c)
            EXPECT_EQ(half_to_float(v.rgb[3 * s + c]), half_to_float(float_to_half(std::array{0.2f, 0.4f, 0.8f}[c])))
                << to_string(m) << ": the colour buffer holds the background";
          if (ac) {
            const uint8_t* a = v.accum + size_t(s) * sample_bytes(fmt.accum);
            EXPECT_EQ(target_load(fmt.accum, a, 3), w ? 1.0f : 0.0f) << to_string(m) << " sample " << s;
            if (w) {
              EXPECT_EQ(target_load(fmt.accum, a, 0), 1.0f) << to_string(m) << ": the src-over colour";
            }
          } else {
            const uint8_t* t = v.trans + size_t(s) * sample_bytes(fmt.transmittance);
            EXPECT_EQ(target_load(fmt.transmittance, t, 0), w ? 0.0f : 1.0f) << to_string(m) << " sample " << s;
          }
        }
      }
    EXPECT_EQ(written, 4 * 8) << to_string(m) << ": R = 8 of 16 samples per pixel at alpha 1/2";
    // Without an opaque draw: today's targets, no mark.
    const StoreTargets plain = store_targets(header(2, 2, 16, {src_over(1, e)}), config(m));
    EXPECT_EQ(plain.accum, uses_accum(m)) << to_string(m);
    EXPECT_EQ(plain.transmittance, uses_transmittance(m)) << to_string(m);
  }
}

namespace {

/// The opaque frame's draws retargeted to encoding e.
TraceHeader with_encoding(TraceHeader h, TargetEncoding e) {
  std::vector<DrawState> d = h.draws.states();
  for (DrawState& s : d) s.encoding = e;
  h.draws = DrawTable(d);
  return h;
}

std::unique_ptr<StochasticModel> run_stochastic(const TraceHeader& h, const std::vector<Fragment>& frags, Method m) {
  auto model = std::make_unique<StochasticModel>(h, config(m));
  for (int p = 0; p < model->passes(); ++p) {
    model->begin_pass(p);
    for (const Fragment& f : frags) model->draw(f);
  }
  return model;
}

}  // namespace

TEST(DrawRoutes, AnEightBitTargetsColourIsRgba8InMemory) {
  // The surfaces' bytes a sample in memory (surface_bytes.h): an 8-bit
  // target's colour buffer and blend's framebuffer are RGBA8, 4 bytes; a
  // float target keeps the store's RGB binary16 (6) and RGBA binary32 (16),
  // as does a frame without draw states; the methods' own targets keep the
  // design's formats. The counters follow, sample for sample.
  TraceHeader h8;
  const std::vector<Fragment> f = opaque_frame(h8, 16);
  const TraceHeader hf = with_encoding(h8, TargetEncoding::kFloat);
  TraceHeader plain = h8;
  plain.draws = DrawTable();
  const BlendFormats fmt;
  for (TargetEncoding e : {TargetEncoding::kUnorm8, TargetEncoding::kSrgb8, TargetEncoding::kFloat}) {
    const TraceHeader h = with_encoding(h8, e);
    const bool rgba8 = e != TargetEncoding::kFloat;
    const SurfaceBytes blend = FunctionalRop(h, config(Method::kBlend)).setup().bytes;
    const SurfaceBytes wboit = FunctionalRop(h, config(Method::kWboit)).setup().bytes;
    EXPECT_EQ(blend.of(Buffer::kColor), rgba8 ? 4u : 6u) << to_string(e);
    EXPECT_EQ(blend.of(Buffer::kAccum), rgba8 ? 4u : 16u) << to_string(e) << ": blend's framebuffer";
    EXPECT_EQ(blend.of(Buffer::kDepth), 4u) << to_string(e);
    EXPECT_EQ(wboit.of(Buffer::kAccum), sample_bytes(fmt.accum)) << to_string(e) << ": wboit's own target";
    EXPECT_EQ(wboit.of(Buffer::kTransmittance), sample_bytes(fmt.transmittance)) << to_string(e);
  }
  const SurfaceBytes none = FunctionalRop(plain, config(Method::kLk)).setup().bytes;
  EXPECT_EQ(none.of(Buffer::kColor), kColorSampleBytes) << "a frame without draw states";
  EXPECT_FALSE(none.converts(Buffer::kColor));
  const Counters b8 = run(h8, f, Method::kBlend)->counters(), bf = run(hf, f, Method::kBlend)->counters();
  ASSERT_GT(b8.target_bytes_written, 0u);
  EXPECT_EQ(b8.samples_blended, bf.samples_blended);
  EXPECT_EQ(b8.target_bytes_written * 16, bf.target_bytes_written * 4) << "blend's framebuffer: 4 bytes against 16";
  EXPECT_EQ(b8.target_bytes_read * 16, bf.target_bytes_read * 4);
  const Counters l8 = run(h8, f, Method::kLk)->counters(), lf = run(hf, f, Method::kLk)->counters();
  ASSERT_GT(l8.color_bytes_written, 0u);
  EXPECT_EQ(l8.samples_written, lf.samples_written);
  EXPECT_EQ(l8.color_bytes_written * 6, lf.color_bytes_written * 4) << "lk's colour buffer: 4 bytes against 6";
  // Compression sees the same tiles, each of tile_pixels x spp x 4 bytes.
  CompressionSetup cs;
  cs.depth = cs.color = true;
  cs.format.depth_encoder = DepthEncoder::kFit;  // the stores keep no plane keys (their runs compress nothing)
  const CompressionStats c8 = measure_compressibility(run_stochastic(h8, f, Method::kLk)->store(), cs);
  const CompressionStats cf = measure_compressibility(run_stochastic(hf, f, Method::kLk)->store(), cs);
  const BufferCompression &k8 = c8.buffers[size_t(Buffer::kColor)], &kf = cf.buffers[size_t(Buffer::kColor)];
  ASSERT_GT(kf.bytes_uncompressed, 0u);
  EXPECT_EQ(k8.tiles_cleared, kf.tiles_cleared);
  EXPECT_EQ(k8.bytes_uncompressed * 6, kf.bytes_uncompressed * 4) << "the colour surface's uncompressed bytes";
  EXPECT_LE(k8.bytes_compressed, k8.bytes_uncompressed);
}

TEST(DrawRoutes, AnEightBitTargetStoresEachWrittenColourAsItsCode) {
  // A method's colour buffer holds what the target stores: on a unorm8
  // target a written colour is its 8-bit code, so src-over draws at alpha 1
  // (every method keeps every nearest sample) give exactly blend's image.
  // The pixel below holds two fragments' colours on 4 and 12 of its 16
  // samples, each colour 0.45 of a code above its code (77 and 128): the
  // stored codes resolve to (77 + 3 x 128) / 4 = 115.25, so code 115, where
  // unrounded colours would resolve to 115.7, code 116.
  const TargetEncoding e = TargetEncoding::kUnorm8;
  const TraceHeader h = header(2, 1, 16, {src_over(0, e), src_over(1, e)});
  const float a = 77.45f / 255.0f, b = 128.45f / 255.0f;
  std::vector<Fragment> f = {frag(0, 0, 0, 0.5f, {a, a, a, 1.0f}, 0x000Full),
                             frag(1, 0, 0, 0.5f, {b, b, b, 1.0f}, 0xFFF0ull),
                             frag(0, 1, 0, 0.6f, {b, a, b, 1.0f}, all_samples(16)),  // behind the next
                             frag(1, 1, 0, 0.4f, {a, b, a, 1.0f}, all_samples(16))};
  const Image want = run(h, f, Method::kBlend)->resolve();
  EXPECT_EQ(want.at(0, 0)[0], fb::srgb_decode_code(115)) << "blend's resolve of the stored codes (as light)";
  for (Method m : kSinglePass) expect_same_image(run(h, f, m)->resolve(), want, to_string(m));
}
