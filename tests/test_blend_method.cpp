// The `blend` method (docs/methods.md "blend"): every fragment blended in
// submission order with its draw's own state, into a target of the draw's
// encoding. Each blend factor and equation against a hand computation in
// unorm8, srgb8 and float; the depth functions and the depth write mask; the
// colour mask; its order against the A-buffer reference; its PNG.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <string>
#include <vector>

#include "rtl_models/golden/golden_model.h"
#include "sim/image/image_io.h"
#include "traces/raster/sample_patterns.h"
#include "util/codec/image_codec.h"

using namespace ropsim;

namespace {

TraceHeader header(uint32_t w, uint32_t h, int spp, std::vector<DrawState> draws) {
  TraceHeader hd;
  hd.width = w;
  hd.height = h;
  hd.spp = spp;
  hd.positions = standard_sample_positions(spp);
  hd.draws = DrawTable(std::move(draws));
  return hd;
}

Fragment frag(uint32_t draw, uint32_t x, uint32_t y, float z, std::array<float, 4> rgba, int spp = 1) {
  Fragment f;
  f.draw_id = draw;
  f.x = uint16_t(x);
  f.y = uint16_t(y);
  f.coverage = spp == 64 ? ~0ull : (1ull << spp) - 1;
  f.z0 = z;
  f.rgb = {rgba[0], rgba[1], rgba[2]};
  f.alpha = rgba[3];
  return f;
}

/// A draw that writes its colour as it is (blending off), depth test off.
DrawState replace_draw(uint32_t id, TargetEncoding e) {
  DrawState s = default_draw_state(id);
  s.blend = false;
  s.depth_test = false;
  s.encoding = e;
  return s;
}

GoldenConfig blend_config() {
  GoldenConfig c;
  c.method = Method::kBlend;
  return c;
}

/// The golden model of `blend` after the fragments, in order.
std::unique_ptr<StochasticModel> run_blend(const TraceHeader& h, const std::vector<Fragment>& frags) {
  auto m = std::make_unique<StochasticModel>(h, blend_config());
  for (const Fragment& f : frags) m->draw(f);
  return m;
}

/// Sample s of pixel (x, y) of the framebuffer, as stored (RGBA).
std::array<float, 4> stored(const StochasticModel& m, uint32_t x, uint32_t y, int s = 0) {
  const PixelView v = m.pixel_view(x, y);
  std::array<float, 4> out{};
  EXPECT_NE(v.accum, nullptr) << "blend keeps its framebuffer in the accumulation target";
  if (v.accum) std::memcpy(out.data(), v.accum + size_t(s) * 16, 16);
  return out;
}

/// The stored byte of an 8-bit channel (stored as code / 255).
int code(float v) { return int(std::lround(v * 255.0f)); }

/// IEC 61966-2-1 sRGB code -> linear, computed here independently.
double srgb_decode(int q) {
  const double c = q / 255.0;
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

using F = BlendFactor;
using E = BlendEquation;

struct BlendCase {
  E eq_rgb, eq_alpha;
  F src_rgb, dst_rgb, src_alpha, dst_alpha;
  std::array<int, 4> unorm8, srgb8;  ///< the stored bytes, computed by hand
  std::array<double, 4> value;       ///< float: the result, computed by hand
};

// Source (0.8, 0.4, 0.2, 0.6); destination bytes (51, 102, 153, 204), i.e.
// (0.2, 0.4, 0.6, 0.8) (srgb8: those codes decoded to linear for R, G, B);
// constant colour (0.25, 0.25, 1.0, 0.4). unorm8 in 8-bit fixed point:
// source bytes (204, 102, 51, 153), constant bytes (64, 64, 255, 102), each
// product x y / 255 rounded to a byte, the sum saturated (e.g. SRC_ALPHA,
// ONE_MINUS_SRC_ALPHA red: round(204 * 153 / 255) + round(51 * 102 / 255) =
// 122 + 20 = 142, where binary32 would round 0.56 to 143); srgb8:
// round(255 encode(clamp(r))) of the binary32 blend, alpha as unorm8.
const BlendCase kCases[] = {
    {E::kAdd,
     E::kAdd,
     F::kSrcAlpha,
     F::kOneMinusSrcAlpha,
     F::kOne,
     F::kOneMinusSrcAlpha,
     {142, 102, 92, 235},
     {186, 147, 136, 235},
     {0.56, 0.4, 0.36, 0.92}},
    {E::kAdd,
     E::kAdd,
     F::kOne,
     F::kOne,
     F::kOne,
     F::kOne,
     {255, 204, 204, 255},
     {235, 193, 191, 255},
     {1.0, 0.8, 0.8, 1.4}},
    {E::kSubtract,
     E::kSubtract,
     F::kOne,
     F::kOne,
     F::kOne,
     F::kOne,
     {153, 0, 0, 0},
     {227, 141, 0, 0},
     {0.6, 0.0, -0.4, -0.2}},
    {E::kReverseSubtract,
     E::kReverseSubtract,
     F::kOne,
     F::kOne,
     F::kOne,
     F::kOne,
     {0, 0, 102, 51},
     {0, 0, 97, 51},
     {-0.6, 0.0, 0.4, 0.2}},
    {E::kMin,
     E::kMax,
     F::kOne,
     F::kZero,
     F::kZero,
     F::kOne,
     {51, 102, 51, 204},
     {51, 102, 124, 204},
     {0.2, 0.4, 0.2, 0.8}},
    {E::kAdd,
     E::kAdd,
     F::kDstColor,
     F::kZero,
     F::kDstAlpha,
     F::kZero,
     {41, 41, 31, 122},
     {45, 65, 71, 122},
     {0.16, 0.16, 0.12, 0.48}},
    {E::kAdd,
     E::kAdd,
     F::kOneMinusDstColor,
     F::kSrcColor,
     F::kOneMinusDstAlpha,
     F::kSrcAlpha,
     {204, 102, 51, 153},
     {231, 170, 124, 153},
     {0.8, 0.4, 0.2, 0.6}},
    {E::kAdd,
     E::kAdd,
     F::kDstAlpha,
     F::kOneMinusDstAlpha,
     F::kZero,
     F::kOne,
     {173, 102, 72, 204},
     {210, 159, 130, 204},
     {0.68, 0.4, 0.28, 0.8}},
    {E::kAdd,
     E::kAdd,
     F::kConstantColor,
     F::kOneMinusConstantColor,
     F::kConstantAlpha,
     F::kOneMinusConstantAlpha,
     {89, 102, 51, 183},
     {130, 123, 124, 184},
     {0.35, 0.4, 0.2, 0.72}},
    {E::kAdd,
     E::kAdd,
     F::kSrcAlphaSaturate,
     F::kOne,
     F::kSrcAlphaSaturate,
     F::kZero,
     {92, 122, 163, 153},
     {122, 127, 161, 153},
     {0.36, 0.48, 0.64, 0.6}},
    {E::kAdd,
     E::kSubtract,
     F::kOneMinusSrcColor,
     F::kOneMinusConstantColor,
     F::kOneMinusSrcAlpha,
     F::kOneMinusConstantAlpha,
     {79, 137, 41, 0},
     {119, 158, 111, 0},
     {0.31, 0.54, 0.16, -0.24}},
};

}  // namespace

TEST(BlendMethod, EveryFactorAndEquationMatchesAHandComputationInEachEncoding) {
  const std::array<int, 4> dst_codes = {51, 102, 153, 204};
  for (TargetEncoding e : {TargetEncoding::kUnorm8, TargetEncoding::kSrgb8, TargetEncoding::kFloat}) {
    for (const BlendCase& c : kCases) {
      DrawState s = default_draw_state(1);
      s.encoding = e;
      s.depth_test = false;
      s.eq_rgb = c.eq_rgb;
      s.eq_alpha = c.eq_alpha;
      s.src_rgb = c.src_rgb;
      s.dst_rgb = c.dst_rgb;
      s.src_alpha = c.src_alpha;
      s.dst_alpha = c.dst_alpha;
      s.blend_color = {0.25f, 0.25f, 1.0f, 0.4f};
      const TraceHeader h = header(1, 1, 1, {replace_draw(0, e), s});
      // The destination: bytes 51, 102, 153, 204 (srgb8: their linear values).
      std::array<float, 4> dst;
      for (int ch = 0; ch < 4; ++ch)
        dst[size_t(ch)] = e == TargetEncoding::kSrgb8 && ch < 3 ? float(srgb_decode(dst_codes[size_t(ch)]))
                                                                : float(dst_codes[size_t(ch)]) / 255.0f;
      const auto m = run_blend(h, {frag(0, 0, 0, 0.5f, dst), frag(1, 0, 0, 0.5f, {0.8f, 0.4f, 0.2f, 0.6f})});
      const std::array<float, 4> got = stored(*m, 0, 0);
      const std::string what = std::string(to_string(e)) + " " + to_string(c.eq_rgb) + "/" + to_string(c.eq_alpha) +
                               " " + to_string(c.src_rgb) + ", " + to_string(c.dst_rgb) + "; " +
                               to_string(c.src_alpha) + ", " + to_string(c.dst_alpha);
      for (int ch = 0; ch < 4; ++ch) {
        if (e == TargetEncoding::kFloat)
          EXPECT_NEAR(got[size_t(ch)], c.value[size_t(ch)], 1e-6) << what << " channel " << ch;
        else
          EXPECT_EQ(code(got[size_t(ch)]), (e == TargetEncoding::kUnorm8 ? c.unorm8 : c.srgb8)[size_t(ch)])
              << what << " channel " << ch;
      }
    }
  }
}

TEST(BlendMethod, FixedPointTargetsClampTheSourceAndTheConstantFloatDoesNot) {
  // Source (1.5, -0.5, 0.5, 2): ONE, ZERO stores it; unorm8 clamps each
  // channel to [0, 1] (bytes 255, 0, 128, 255), float keeps it. The constant
  // colour 2 clamps to 1 on unorm8: CONSTANT_COLOR, ZERO of source 0.5 is 0.5.
  for (TargetEncoding e : {TargetEncoding::kUnorm8, TargetEncoding::kFloat}) {
    DrawState s = default_draw_state(0);
    s.encoding = e;
    s.depth_test = false;
    s.src_rgb = s.src_alpha = F::kOne;
    s.dst_rgb = s.dst_alpha = F::kZero;
    DrawState k = s;
    k.draw_id = 1;
    k.src_rgb = k.src_alpha = F::kConstantColor;
    k.blend_color = {2.0f, 2.0f, 2.0f, 2.0f};
    const auto m = run_blend(header(2, 1, 1, {s, k}), {frag(0, 0, 0, 0.5f, {1.5f, -0.5f, 0.5f, 2.0f}),
                                                       frag(1, 1, 0, 0.5f, {0.5f, 0.5f, 0.5f, 0.5f})});
    const auto a = stored(*m, 0, 0), b = stored(*m, 1, 0);
    if (e == TargetEncoding::kUnorm8) {
      EXPECT_EQ(code(a[0]), 255);
      EXPECT_EQ(code(a[1]), 0);
      EXPECT_EQ(code(a[2]), 128);  // 127.5 rounds up
      EXPECT_EQ(code(a[3]), 255);
      EXPECT_EQ(code(b[0]), 128) << "the constant colour clamps to 1 on a unorm8 target";
    } else {
      EXPECT_EQ(a[0], 1.5f);
      EXPECT_EQ(a[1], -0.5f);
      EXPECT_EQ(a[3], 2.0f);
      EXPECT_EQ(b[0], 1.0f) << "a float target keeps the constant colour 2";
    }
  }
}

TEST(BlendMethod, Unorm8QuantizesAfterEveryBlend) {
  // Ten additive blends of 0.001 each onto 0: every one rounds back to byte 0
  // (0.001 * 255 = 0.255), so the target stays 0; a float target sums to 0.01.
  for (TargetEncoding e : {TargetEncoding::kUnorm8, TargetEncoding::kFloat}) {
    DrawState s = default_draw_state(0);
    s.encoding = e;
    s.depth_test = false;
    s.src_rgb = s.dst_rgb = s.src_alpha = s.dst_alpha = F::kOne;
    TraceHeader h = header(1, 1, 1, {s});
    h.clear_color = {0, 0, 0};
    std::vector<Fragment> frags(10, frag(0, 0, 0, 0.5f, {0.001f, 0.001f, 0.001f, 0.0f}));
    const auto m = run_blend(h, frags);
    const float r = stored(*m, 0, 0)[0];
    if (e == TargetEncoding::kUnorm8)
      EXPECT_EQ(r, 0.0f) << "each blend reads the quantized destination";
    else
      EXPECT_NEAR(r, 0.01f, 1e-7);
  }
}

TEST(BlendMethod, DepthFunctionsAndTheWriteMask) {
  // Stored depth 0.5 (a first draw: ALWAYS, writing). Then one fragment of
  // depth z per function; it passes exactly when GL's function says.
  struct Case {
    DepthFunc f;
    bool less, equal, greater;  // passes for z = 0.4, 0.5, 0.6
  };
  const Case cases[] = {{DepthFunc::kNever, false, false, false},  {DepthFunc::kLess, true, false, false},
                        {DepthFunc::kEqual, false, true, false},   {DepthFunc::kLequal, true, true, false},
                        {DepthFunc::kGreater, false, false, true}, {DepthFunc::kNotequal, true, false, true},
                        {DepthFunc::kGequal, false, true, true},   {DepthFunc::kAlways, true, true, true}};
  for (const Case& c : cases) {
    DrawState base = replace_draw(0, TargetEncoding::kFloat);
    base.depth_test = true;
    base.depth_func = DepthFunc::kAlways;
    base.depth_write = true;
    DrawState t = replace_draw(1, TargetEncoding::kFloat);
    t.depth_test = true;
    t.depth_func = c.f;
    const TraceHeader h = header(3, 1, 1, {base, t});
    std::vector<Fragment> frags;
    const float zs[3] = {0.4f, 0.5f, 0.6f};
    for (uint32_t x = 0; x < 3; ++x) frags.push_back(frag(0, x, 0, 0.5f, {0, 0, 0, 1}));
    for (uint32_t x = 0; x < 3; ++x) frags.push_back(frag(1, x, 0, zs[x], {1, 1, 1, 1}));
    const auto m = run_blend(h, frags);
    const bool want[3] = {c.less, c.equal, c.greater};
    for (uint32_t x = 0; x < 3; ++x)
      EXPECT_EQ(stored(*m, x, 0)[0] == 1.0f, want[x]) << to_string(c.f) << " at z " << zs[x] << " against 0.5";
  }
  // The write mask: a LESS draw without depth writes leaves 1 (the clear), so
  // a later, farther LESS fragment still passes; with writes it fails. A draw
  // with its test off writes no depth, whatever its mask.
  for (int variant = 0; variant < 3; ++variant) {
    DrawState near = replace_draw(0, TargetEncoding::kFloat);
    near.depth_test = variant != 2;
    near.depth_func = DepthFunc::kLess;
    near.depth_write = variant != 0;
    DrawState far = replace_draw(1, TargetEncoding::kFloat);
    far.depth_test = true;
    far.depth_func = DepthFunc::kLess;
    const auto m =
        run_blend(header(1, 1, 1, {near, far}), {frag(0, 0, 0, 0.3f, {0, 0, 0, 1}), frag(1, 0, 0, 0.4f, {1, 1, 1, 1})});
    const bool wrote = variant == 1;
    EXPECT_EQ(stored(*m, 0, 0)[0], wrote ? 0.0f : 1.0f) << (variant == 0   ? "test on, mask off"
                                                            : variant == 1 ? "test on, mask on"
                                                                           : "test off, mask on");
    EXPECT_EQ(m->pixel_view(0, 0).depth[0], wrote ? 0.3f : 1.0f);
    EXPECT_EQ(m->counters().depth_bytes_written, wrote ? 4u : 0u);
  }
}

TEST(BlendMethod, TheColourMaskKeepsTheMaskedChannels) {
  DrawState s = replace_draw(1, TargetEncoding::kUnorm8);
  s.color_mask = 0x5;  // red and blue
  const auto m = run_blend(header(1, 1, 1, {replace_draw(0, TargetEncoding::kUnorm8), s}),
                           {frag(0, 0, 0, 0.5f, {0.2f, 0.4f, 0.6f, 0.8f}), frag(1, 0, 0, 0.5f, {1, 1, 1, 1})});
  const auto v = stored(*m, 0, 0);
  EXPECT_EQ(code(v[0]), 255);
  EXPECT_EQ(code(v[1]), 102) << "green is masked";
  EXPECT_EQ(code(v[2]), 255);
  EXPECT_EQ(code(v[3]), 204) << "alpha is masked";
}

TEST(BlendMethod, DiffersFromTheReferenceOnlyByOrder) {
  // An opaque far surface, then two src-over fragments over it (the default
  // draw state: depth test LESS, no writes). Submitted back to front, blend
  // composites as the A-buffer does (to binary16 rounding of the opaque
  // colour, which the reference's colour buffer holds); front to back it
  // differs, and equals the over operator in submission order.
  DrawState opaque = replace_draw(0, TargetEncoding::kFloat);
  opaque.depth_test = true;
  opaque.depth_write = true;
  const std::array<float, 4> bg = {0.1f, 0.2f, 0.9f, 1.0f}, red = {1, 0, 0, 0.5f}, green = {0, 1, 0, 0.5f};
  for (bool back_to_front : {true, false}) {
    const TraceHeader h = header(1, 1, 1, {opaque, default_draw_state(1), default_draw_state(2)});
    std::vector<Fragment> frags = {frag(0, 0, 0, 0.9f, bg)};
    const Fragment r = frag(1, 0, 0, 0.5f, red), g = frag(2, 0, 0, 0.3f, green);  // green is nearer
    if (back_to_front) {
      frags.push_back(r);
      frags.push_back(g);
    } else {
      frags.push_back(g);
      frags.push_back(r);
    }
    const auto m = run_blend(h, frags);
    ReferenceModel ref(h);
    for (const Fragment& f : frags) ref.draw(f);
    const Image bi = m->resolve(), ai = ref.resolve();
    const float *b = bi.at(0, 0), *a = ai.at(0, 0);
    // Hand over-composite: far to near for the reference; submission order for blend.
    const double sorted[3] = {0.5 * 0.5 * 0.1 + 0.5 * 0.5 * 1.0, 0.5 * 0.5 * 0.2 + 0.5, 0.5 * 0.5 * 0.9};
    const double submitted[3] = {0.5 * 0.5 * 0.1 + 0.5, 0.5 * 0.5 * 0.2 + 0.5 * 0.5, 0.5 * 0.5 * 0.9};
    for (int c = 0; c < 3; ++c) {
      // The reference keeps the opaque draw in its colour buffer, RGB binary16.
      EXPECT_NEAR(a[c], sorted[c], 2e-4) << "reference channel " << c;
      EXPECT_NEAR(b[c], back_to_front ? sorted[c] : submitted[c], 1e-6)
          << (back_to_front ? "back to front" : "front to back") << " channel " << c;
    }
    if (!back_to_front) {
      EXPECT_GT(std::fabs(double(a[0]) - double(b[0])), 0.2) << "order matters to blend";
    }
  }
}

TEST(BlendMethod, MultisampleResolveAveragesInTheTargetsEncoding) {
  // 4 spp, two samples white and two black: float averages to 0.5; unorm8
  // rounds the mean to byte 128; srgb8 averages in linear (0.5) and encodes
  // (byte 188).
  for (TargetEncoding e : {TargetEncoding::kFloat, TargetEncoding::kUnorm8, TargetEncoding::kSrgb8}) {
    const TraceHeader h = header(1, 1, 4, {replace_draw(0, e)});
    Fragment f = frag(0, 0, 0, 0.5f, {1, 1, 1, 1}, 4);
    f.coverage = 0x3;
    const auto m = run_blend(h, {f});
    const Image img = m->resolve();
    const float v = img.at(0, 0)[0];
    if (e == TargetEncoding::kFloat) {
      EXPECT_EQ(v, 0.5f);
    } else {
      const int byte = int(std::lround(linear_to_srgb(v) * 255.0f));
      EXPECT_EQ(byte, e == TargetEncoding::kUnorm8 ? 128 : 188) << to_string(e);
    }
  }
}

TEST(BlendMethod, ThePngHoldsTheTargetsStoredBytes) {
  // Every byte 0..255 stored by a unorm8 and an srgb8 target comes out of
  // the PNG as that byte (no second transfer function); the clear colour's
  // too (pixel 256 is untouched: clear 0.5 linear, unorm8 byte 128).
  for (TargetEncoding e : {TargetEncoding::kUnorm8, TargetEncoding::kSrgb8}) {
    TraceHeader h = header(257, 1, 1, {replace_draw(0, e)});
    h.clear_color = {0.5f, 0.5f, 0.5f};
    std::vector<Fragment> frags;
    for (uint32_t x = 0; x < 256; ++x) {
      const float v = e == TargetEncoding::kSrgb8 ? float(srgb_decode(int(x))) : float(x) / 255.0f;
      frags.push_back(frag(0, x, 0, 0.5f, {v, v, v, 1}));
    }
    const auto m = run_blend(h, frags);
    for (uint32_t x = 0; x < 256; ++x) ASSERT_EQ(code(stored(*m, x, 0)[0]), int(x)) << to_string(e) << " byte " << x;
    const std::string path = "/tmp/ropsim_blend_png_" + std::to_string(getpid()) + ".png";
    write_image(m->resolve(), path);
    const DecodedImage d = decode_image_file(path);
    std::remove(path.c_str());
    ASSERT_EQ(d.width, 257);
    for (int x = 0; x < 256; ++x)
      EXPECT_EQ(int(std::lround(d.px[size_t(x) * size_t(d.channels)] * 255.0f)), x) << to_string(e) << " byte " << x;
    const int clear_byte = e == TargetEncoding::kUnorm8 ? 128 : 188;
    EXPECT_EQ(int(std::lround(d.px[256 * size_t(d.channels)] * 255.0f)), clear_byte) << to_string(e) << " clear";
  }
}

TEST(BlendMethod, AnEmptyDrawTableBlendsSrcOverInFloatInSubmissionOrder) {
  // No draw states: every draw src-over, depth LESS without writes, float.
  TraceHeader h = header(1, 1, 1, {});
  h.clear_color = {0, 0, 1};
  const auto m = run_blend(h, {frag(0, 0, 0, 0.2f, {1, 0, 0, 0.5f}), frag(1, 0, 0, 0.9f, {0, 1, 0, 0.25f})});
  const Image img = m->resolve();
  const float* px = img.at(0, 0);
  // ((0,0,1) over-ed by red at 0.5, then green at 0.25; depth is never written).
  EXPECT_NEAR(px[0], 0.5 * 0.75, 1e-7);
  EXPECT_NEAR(px[1], 0.25, 1e-7);
  EXPECT_NEAR(px[2], 0.5 * 0.75, 1e-7);
}
