// The GL capture's plain-C++ rules (traces/glcapture/fragment_order.h,
// glsl_rewrite.h; docs/capture.md "Capturing a GL frame"): the per-pass
// sample offset, the decoding of a pass's records, the API order rebuilt
// from ids, and the shader rewrite. No GL context needed.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <tuple>

#include "tests/compare_util.h"
#include "traces/glcapture/fragment_order.h"
#include "traces/glcapture/glsl_rewrite.h"
#include "traces/raster/sample_patterns.h"

namespace ropsim::glcapture {
namespace {

PassRecord rec(uint32_t part, uint32_t instance, uint32_t prim, uint16_t x, uint16_t y, int sample, float z,
               float red = 0.5f) {
  PassRecord r;
  r.part = part;
  r.instance = instance;
  r.prim = prim;
  r.x = x;
  r.y = y;
  r.sample = uint8_t(sample);
  r.z = z;
  r.rgba = {red, 0.25f, 0.125f, 0.5f};
  return r;
}

// Moving the geometry by the pass's offset brings every standard sample
// position of every pixel onto that pixel's centre, in GL's y-up window
// coordinates, for every pattern and an odd viewport.
TEST(GlCaptureOffsets, EachSamplePositionMovesOntoThePixelCentre) {
  const int vw = 37, vh = 23;
  for (int spp : {1, 2, 4, 8, 16, 32, 64}) {
    const auto pos = standard_sample_positions(spp);
    for (int s = 0; s < spp; ++s) {
      const std::array<float, 2> off = sample_clip_offset(pos[size_t(s)], vw, vh);
      for (int py : {0, 5, vh - 1}) {
        // The sample in trace coordinates (y down), then in GL window coordinates (y up).
        const double tx = 3 + pos[size_t(s)].x / 256.0, ty = py + pos[size_t(s)].y / 256.0;
        const double gx = tx, gy = vh - ty;
        // NDC offset -> window units: half the viewport.
        const double mx = gx + off[0] * vw / 2.0, my = gy + off[1] * vh / 2.0;
        EXPECT_NEAR(mx, 3.5, 1e-5) << spp << " spp, sample " << s;
        EXPECT_NEAR(my, (vh - 1 - py) + 0.5, 1e-5) << spp << " spp, sample " << s << ", row " << py;
      }
    }
  }
}

TEST(GlCaptureOffsets, OnlyPatternsWithoutACentreSampleNeedACentrePass) {
  EXPECT_FALSE(needs_centre_pass(standard_sample_positions(1), 1));
  for (int spp : {2, 4, 8, 16, 32, 64})
    EXPECT_TRUE(needs_centre_pass(standard_sample_positions(spp), spp)) << spp << " spp";
}

TEST(GlCaptureOrder, DecodingFlipsRowsAndRefusesPixelsOutsideAndDepthsOutsideZeroOne) {
  auto word = [](float f) {
    uint32_t u;
    std::memcpy(&u, &f, 4);
    return u;
  };
  std::vector<uint32_t> raw = {5u | (0u << 16), 7, 2, word(0.25f), word(1), word(0), word(0), word(1),
                               6u | (9u << 16), 8, 0, word(0.5f),  word(0), word(1), word(0), word(1)};
  std::vector<PassRecord> out;
  ASSERT_EQ(decode_records(raw.data(), 2, 16, 10, 3, 4, out), "");
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0].x, 5);
  EXPECT_EQ(out[0].y, 9);  // GL row 0 is the bottom: trace row height - 1
  EXPECT_EQ(out[1].y, 0);
  EXPECT_EQ(out[0].prim, 7u);
  EXPECT_EQ(out[0].instance, 2u);
  EXPECT_EQ(out[0].part, 3u);
  EXPECT_EQ(out[0].sample, 4);
  EXPECT_EQ(out[0].z, 0.25f);
  raw[8] = 6u | (10u << 16);  // row 10 of a 10-row target
  out.clear();
  EXPECT_NE(decode_records(raw.data(), 2, 16, 10, 0, 0, out).find("outside the 16x10 target"), std::string::npos);
  raw[8] = 6u | (9u << 16);
  raw[11] = word(1.5f);
  out.clear();
  EXPECT_NE(decode_records(raw.data(), 2, 16, 10, 0, 0, out).find("not in [0, 1]"), std::string::npos);
}

// Fragments in (part, instance, primitive, row, column) order, each pass's
// coverage bit and depth merged, and the same bytes whatever order the
// passes' records arrived in (llvmpipe's threads).
TEST(GlCaptureOrder, FragmentsComeInApiOrderWhateverTheRecordOrder) {
  std::vector<PassRecord> base;
  for (uint32_t part = 0; part < 2; ++part)
    for (uint32_t inst = 0; inst < 2; ++inst)
      for (uint32_t prim = 0; prim < 3; ++prim)
        for (uint16_t y = 0; y < 3; ++y)
          for (uint16_t x = 0; x < 3; ++x)
            for (int s = 0; s < 4; ++s)
              if ((x + y + s + prim) % 3 != 0)
                base.push_back(rec(part, inst, prim, x, y, s, 0.1f * float(s) + 0.01f * float(prim)));
  std::vector<CapturedFragment> expected;
  std::vector<PassRecord> sorted = base;
  ASSERT_EQ(build_fragments(sorted, 7, {{3}, {3}}, true, expected), "");
  ASSERT_FALSE(expected.empty());
  for (size_t i = 1; i < expected.size(); ++i) {
    const auto& a = expected[i - 1];
    const auto& b = expected[i];
    EXPECT_TRUE(std::make_tuple(a.prim_id, a.y, a.x) < std::make_tuple(b.prim_id, b.y, b.x)) << "fragment " << i;
  }
  for (const auto& f : expected) {
    EXPECT_EQ(f.draw_id, 7u);
    EXPECT_EQ(size_t(__builtin_popcountll(f.coverage)), f.z.size());
    size_t k = 0;
    for (uint64_t m = f.coverage; m; m &= m - 1, ++k)
      EXPECT_FLOAT_EQ(f.z[k], 0.1f * float(__builtin_ctzll(m)) + 0.01f * float(f.prim_id % 3));
  }
  std::mt19937 rng(12345);
  for (int trial = 0; trial < 5; ++trial) {
    std::vector<PassRecord> shuffled = base;
    std::shuffle(shuffled.begin(), shuffled.end(), rng);
    std::vector<CapturedFragment> got;
    ASSERT_EQ(build_fragments(shuffled, 7, {{3}, {3}}, true, got), "");
    ASSERT_EQ(got.size(), expected.size());
    for (size_t i = 0; i < got.size(); ++i) {
      EXPECT_EQ(got[i].prim_id, expected[i].prim_id);
      EXPECT_EQ(got[i].x, expected[i].x);
      EXPECT_EQ(got[i].y, expected[i].y);
      EXPECT_EQ(got[i].coverage, expected[i].coverage);
      EXPECT_EQ(got[i].z, expected[i].z);
    }
  }
}

// The fragments equal those of the rule written out directly (each
// (prim_id, pixel)'s records in (sample, depth, colour) order: the first
// record of each sample, the first centre record's colour, else the lowest
// sample's), in (prim_id, row, column) order, for records with repeats,
// parts, instances, centre-only pixels and a pixel with many primitives.
TEST(GlCaptureOrder, FragmentsMatchTheRuleWrittenOutDirectly) {
  std::mt19937 rng(7);
  std::vector<PassRecord> r;
  // More than 2^20 records: build_fragments then splits its work over threads.
  for (int i = 0; i < 1100000; ++i) {
    const int sample = int(rng() % 5) == 0 ? kCentrePass : int(rng() % 16);
    PassRecord a = rec(rng() % 2, rng() % 3, rng() % 4, uint16_t(rng() % 90), uint16_t(rng() % 50), sample,
                       float(rng() % 8) / 8.0f, float(rng() % 4) / 4.0f);
    r.push_back(a);
  }
  for (uint32_t prim = 0; prim < 4; ++prim)  // pixel (8, 4): 4 x 2 x 3 x 17 more records
    for (uint32_t inst = 0; inst < 3; ++inst)
      for (uint32_t part = 0; part < 2; ++part)
        for (int s = 0; s <= 16; ++s) r.push_back(rec(part, inst, prim, 8, 4, s == 16 ? kCentrePass : s, 0.5f));
  std::vector<CapturedFragment> got;
  ASSERT_EQ(build_fragments(r, 2, {{4}, {4}}, true, got), "");

  auto id = [](const PassRecord& a) { return a.part * 12 + a.instance * 4 + a.prim; };
  auto bits = [](float f) {
    uint32_t u;
    std::memcpy(&u, &f, 4);
    return u;
  };
  std::vector<PassRecord> sorted = r;
  std::sort(sorted.begin(), sorted.end(), [&](const PassRecord& a, const PassRecord& b) {
    auto ka = std::make_tuple(id(a), a.y, a.x, a.sample, bits(a.z), bits(a.rgba[0]));
    auto kb = std::make_tuple(id(b), b.y, b.x, b.sample, bits(b.z), bits(b.rgba[0]));
    return ka < kb;
  });
  std::vector<CapturedFragment> want;
  for (size_t i = 0; i < sorted.size();) {
    size_t j = i;
    CapturedFragment f;
    const PassRecord *centre = nullptr, *lowest = nullptr;
    for (; j < sorted.size() && id(sorted[j]) == id(sorted[i]) && sorted[j].x == sorted[i].x &&
           sorted[j].y == sorted[i].y;
         ++j) {
      const PassRecord& a = sorted[j];
      if (a.sample == kCentrePass) {
        if (!centre) centre = &a;
      } else if (!(f.coverage >> a.sample & 1)) {
        if (!lowest) lowest = &a;
        f.coverage |= uint64_t(1) << a.sample;
        f.z.push_back(a.z);
      }
    }
    if (f.coverage) {
      f.prim_id = id(sorted[i]);
      f.x = sorted[i].x;
      f.y = sorted[i].y;
      f.rgba = (centre ? centre : lowest)->rgba;
      want.push_back(f);
    }
    i = j;
  }
  ASSERT_EQ(got.size(), want.size());
  // The target's size given: its pixels as buckets, and, for a target far
  // larger than the records cover, only the pixels they hit; the same fragments.
  for (uint32_t side : {100u, 32768u}) {
    std::vector<CapturedFragment> sized;
    ASSERT_EQ(build_fragments(r, 2, {{4}, {4}}, true, sized, side, side), "");
    ASSERT_EQ(sized.size(), got.size()) << side;
    for (size_t i = 0; i < got.size(); ++i)
      ASSERT_EQ(ropsim_test::Fields()
                    .eq("prim_id", sized[i].prim_id, got[i].prim_id)
                    .eq("x", sized[i].x, got[i].x)
                    .eq("y", sized[i].y, got[i].y)
                    .eq("coverage", sized[i].coverage, got[i].coverage)
                    .eq("z", sized[i].z, got[i].z)
                    .eq("rgba", sized[i].rgba, got[i].rgba)
                    .str(),
                "")
          << side << " x " << side << ": fragment " << i;
  }
  std::vector<CapturedFragment> small;
  EXPECT_NE(build_fragments(r, 2, {{4}, {4}}, true, small, 50, 50).find("outside the 50x50 target"), std::string::npos);
  for (size_t i = 0; i < got.size(); ++i) {
    ASSERT_EQ(got[i].draw_id, 2u);
    ASSERT_EQ(got[i].prim_id, want[i].prim_id) << i;
    ASSERT_EQ(got[i].x, want[i].x) << i;
    ASSERT_EQ(got[i].y, want[i].y) << i;
    ASSERT_EQ(got[i].coverage, want[i].coverage) << i;
    ASSERT_EQ(got[i].z, want[i].z) << i;
    ASSERT_EQ(got[i].rgba, want[i].rgba) << i;
  }
}

// prim_id = the earlier parts' primitives + instance * primitives per
// instance + gl_PrimitiveID; the records raise a count the call understated.
TEST(GlCaptureOrder, PrimitiveIdsNumberInstancesAndPartsOneAfterAnother) {
  std::vector<PassRecord> r = {rec(0, 1, 2, 0, 0, 0, 0.5f), rec(1, 0, 0, 0, 0, 0, 0.5f), rec(1, 2, 4, 0, 0, 0, 0.5f)};
  std::vector<CapturedFragment> out;
  // Part 0: 3 primitives an instance, 2 instances (0..5); part 1: the call
  // says 2 an instance, the records show primitive 4, so 5, 3 instances.
  ASSERT_EQ(build_fragments(r, 0, {{3}, {2}}, true, out), "");
  ASSERT_EQ(out.size(), 3u);
  EXPECT_EQ(out[0].prim_id, 1u * 3 + 2);
  EXPECT_EQ(out[1].prim_id, 6u + 0);
  EXPECT_EQ(out[2].prim_id, 6u + 2 * 5 + 4);
  std::vector<PassRecord> big = {rec(0, 0x10000, 0xFFFF, 0, 0, 0, 0.5f)};
  EXPECT_NE(build_fragments(big, 3, {{0x10000}}, true, out).find("32-bit"), std::string::npos);
}

// Colour: the centre pass's where it covers, else the lowest covered sample's;
// a centre record without a covered sample makes no fragment; a repeated
// sample keeps the smaller depth.
TEST(GlCaptureOrder, ColourFromTheCentreElseTheLowestSampleAndRepeatsKeepTheNearestDepth) {
  std::vector<PassRecord> r = {
      rec(0, 0, 0, 1, 1, 2, 0.75f, 0.2f),          rec(0, 0, 0, 1, 1, 1, 0.5f, 0.1f),
      rec(0, 0, 0, 1, 1, kCentrePass, 0.6f, 0.9f), rec(0, 0, 0, 1, 1, 2, 0.25f, 0.3f),  // repeat of sample 2, nearer
      rec(0, 0, 0, 2, 1, 3, 0.5f, 0.4f),           rec(0, 0, 0, 2, 1, 0, 0.5f, 0.35f),
      rec(0, 0, 0, 3, 1, kCentrePass, 0.5f, 0.8f),  // centre only
  };
  std::vector<CapturedFragment> out;
  ASSERT_EQ(build_fragments(r, 0, {{1}}, true, out), "");
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0].x, 1);
  EXPECT_EQ(out[0].coverage, 0b110u);
  EXPECT_EQ(out[0].z, (std::vector<float>{0.5f, 0.25f}));
  EXPECT_FLOAT_EQ(out[0].rgba[0], 0.9f);  // the centre's
  EXPECT_EQ(out[1].x, 2);
  EXPECT_EQ(out[1].coverage, 0b1001u);
  EXPECT_FLOAT_EQ(out[1].rgba[0], 0.35f);  // sample 0's: no centre record
}

TEST(GlCaptureOrder, ColourIsClampedToWhatTheTargetAndTheTraceHold) {
  PassRecord a = rec(0, 0, 0, 0, 0, 0, 0.5f);
  a.rgba = {1.5f, -0.5f, std::nanf(""), 1.25f};
  std::vector<PassRecord> r = {a};
  std::vector<CapturedFragment> unorm, flt;
  ASSERT_EQ(build_fragments(r, 0, {{1}}, true, unorm), "");
  r = {a};
  ASSERT_EQ(build_fragments(r, 0, {{1}}, false, flt), "");
  EXPECT_EQ(unorm[0].rgba, (std::array<float, 4>{1.0f, 0.0f, 0.0f, 1.0f}));
  EXPECT_EQ(flt[0].rgba, (std::array<float, 4>{1.5f, 0.0f, 0.0f, 1.0f}));
  const Fragment f = to_trace_fragment(unorm[0]);
  EXPECT_EQ(f.coverage, 1u);
  EXPECT_EQ(f.z[0], 0.5f);
  EXPECT_EQ(f.alpha, 1.0f);
}

TEST(GlslRewrite, MainIsRenamedAndTheVersionReplacedCommentsIgnored) {
  const std::string vs =
      "// main( in a comment\n#version 120\nattribute vec3 p;\n/* void main() */\nvoid main(void)\n{ gl_Position = "
      "vec4(p, 1.0); }\n";
  const Rewritten r = instrument_vertex_shader(vs, GlslProfile::kCompatibility);
  ASSERT_EQ(r.error, "");
  EXPECT_EQ(r.source.find("#version 120"), std::string::npos);
  EXPECT_NE(r.source.find("#version 450 compatibility"), std::string::npos);
  EXPECT_NE(r.source.find("void ropsim_app_main(void)"), std::string::npos);
  EXPECT_NE(r.source.find("ropsim_instance = gl_InstanceID;"), std::string::npos);
  EXPECT_NE(r.source.find("gl_Position.xy += ropsim_offset * gl_Position.w;"), std::string::npos);
  // Lines keep their numbers: the comments' newlines are kept.
  EXPECT_EQ(std::count(vs.begin(), vs.end(), '\n'),
            std::count(r.source.begin(), r.source.begin() + long(r.source.find("\n// ropsim capture")), '\n'));
  const Rewritten none =
      instrument_vertex_shader("uniform float k;\nfloat helper() { return k; }\n", GlslProfile::kCore);
  EXPECT_EQ(none.source, "#version 450 core\nuniform float k;\nfloat helper() { return k; }\n");
  const Rewritten fs = instrument_fragment_shader("void main() { gl_FragColor = vec4(1.0); }", GlslProfile::kCore, 5);
  EXPECT_NE(fs.source.find("binding = 5"), std::string::npos);
  EXPECT_NE(fs.source.find("vec4 ropsim_color = gl_FragColor;"), std::string::npos);
  EXPECT_EQ(fs.source.find("mainly"), std::string::npos);
}

TEST(GlslRewrite, TheColourIsTheOutputAtLocationZeroOrTheBuiltIns) {
  EXPECT_EQ(fragment_color_expression("out vec4 a;\nlayout(location = 0) out vec4 b;\nvoid main() {}"), "b");
  EXPECT_EQ(fragment_color_expression("layout(location=1) out highp vec4 a; out vec4 c[2]; void main() {}"), "a");
  EXPECT_EQ(fragment_color_expression("out vec4 frag[2];\nvoid main() {}"), "frag[0]");
  EXPECT_EQ(fragment_color_expression("void main() { vec4 out_not; gl_FragData[0] = vec4(1.0); }"), "gl_FragData[0]");
  EXPECT_EQ(fragment_color_expression("void main() { gl_FragColor = vec4(1.0); }"), "gl_FragColor");
  EXPECT_EQ(fragment_color_expression("void main() { }"), "vec4(0.0, 0.0, 0.0, 1.0)");
  // A local declared `out` parameter inside a function is not the output.
  EXPECT_EQ(fragment_color_expression("void f(out vec4 q) { q = vec4(0.0); }\nvoid main() { gl_FragColor = "
                                      "vec4(1.0); }"),
            "gl_FragColor");
}

// The fragment shader's interpolated inputs are read at the pixel centre of
// the unshifted geometry (where multisampling shades), from their
// derivatives: a smooth input through its product with 1/w (affine in window
// coordinates) divided by 1/w at the centre, a noperspective one directly,
// gl_Color and gl_TexCoord's elements as smooth inputs; flat and centroid
// inputs are left alone, a second declaration on a line is found, and the
// shader's own lines keep their numbers (#line).
TEST(GlslRewrite, InterpolatedInputsAreReadAtThePixelCentre) {
  const std::string fs =
      "#version 330\nin vec2 uv;\nnoperspective in vec3 n;\nflat in int id;\ncentroid in vec4 c;\n"
      "in float f; in vec4 g;\nuniform sampler2D t;\nout vec4 o;\nvec2 at() { return uv * 2.0; }\n"
      "void main() { o = texture(t, at()) + vec4(n, float(id)) + c + gl_Color + gl_TexCoord[1] + f + g; }\n";
  const Rewritten r = instrument_fragment_shader(fs, GlslProfile::kCompatibility, 3);
  ASSERT_EQ(r.error, "");
  const std::string& s = r.source;
  for (const char* want :
       {"#define uv ropsim_c_uv", "#define n ropsim_c_n", "#define f ropsim_c_f", "#define g ropsim_c_g",
        "float ropsim_q = gl_FragCoord.w;", "float ropsim_q_at = ropsim_at_offset(ropsim_q);",
        "ropsim_c_uv = ropsim_moved ? ropsim_at_offset(uv * ropsim_q) / ropsim_q_at : uv;",
        "ropsim_c_n = ropsim_moved ? ropsim_at_offset(n) : n;",
        "ropsim_c_g = ropsim_moved ? ropsim_at_offset(g * ropsim_q) / ropsim_q_at : g;", "#undef uv", "#undef n",
        "ropsim_c_gl_Color = ropsim_moved ? ropsim_at_offset(gl_Color * ropsim_q) / ropsim_q_at : gl_Color;",
        "ropsim_c_gl_TexCoord[1] = ropsim_moved ? ropsim_at_offset(gl_TexCoord[1] * ropsim_q) / ropsim_q_at",
        "uniform vec2 ropsim_pixel_offset;",
        "#define ropsim_at_offset(v) ((v) + dFdx(v) * ropsim_pixel_offset.x + dFdy(v) * ropsim_pixel_offset.y)"})
    EXPECT_NE(s.find(want), std::string::npos) << want << " in\n" << s;
  for (const char* not_there :
       {"ropsim_c_id", "ropsim_c_c ", "ropsim_at_offset(c", "ropsim_c_t", "interpolateAtOffset"})
    EXPECT_EQ(s.find(not_there), std::string::npos) << not_there << " in\n" << s;
  // The copies are filled before the application's main runs.
  EXPECT_LT(s.find("ropsim_c_uv = ropsim_moved"), s.find("  ropsim_app_main();"));
  // What follows `in vec2 uv;` on its line (shader line 2) is numbered 2
  // again, and `noperspective in vec3 n;` keeps its line 3.
  EXPECT_NE(s.find("#define uv ropsim_c_uv\n#define ropsim_has_uv\n#line 2\n\nnoperspective in vec3 n;"),
            std::string::npos)
      << s;
  // No interpolated input: nothing added but the uniform.
  const Rewritten plain =
      instrument_fragment_shader("flat in int k;\nvoid main() { gl_FragColor = vec4(k); }", GlslProfile::kCore, 3);
  EXPECT_EQ(plain.source.find("ropsim_c_"), std::string::npos) << plain.source;
  EXPECT_EQ(plain.source.find("ropsim_q"), std::string::npos) << plain.source;
}

TEST(GlslRewrite, AnInputUnderAPreprocessorBranchIsFilledOnlyWhereTheBranchKeepsIt) {
  // Minetest's node shader declares its texture coordinate once for GLSL ES
  // and once, centroid, for desktop GL; OpenArena's under `#if
  // defined(USE_LIGHT)`. Each copy is declared beside its input, with
  // `#define ropsim_has_NAME`, so it exists only where the preprocessor keeps
  // the declaration, and the wrapper fills it under `#ifdef ropsim_has_NAME`:
  // a copy in a branch that is not compiled is never filled (it would be
  // undeclared).
  const std::string fs =
      "#version 120\n"
      "#ifdef GL_ES\nvarying mediump vec2 varTexCoord;\n#else\ncentroid varying vec2 varTexCoord;\n#endif\n"
      "#if defined(USE_LIGHT)\nvarying vec3 var_Normal;\n#endif\n"
      "uniform sampler2D t;\n"
      "void main() { gl_FragColor = texture2D(t, varTexCoord);\n"
      "#if defined(USE_LIGHT)\n  gl_FragColor.rgb *= var_Normal;\n#endif\n}\n";
  const Rewritten r = instrument_fragment_shader(fs, GlslProfile::kCompatibility, 3);
  ASSERT_EQ(r.error, "");
  const std::string& s = r.source;
  for (const char* name : {"varTexCoord", "var_Normal"}) {
    const std::string n = name;
    // The copy, its #define and its guard, inside the declaration's branch.
    const size_t decl = s.find("varying " + std::string(n == "varTexCoord" ? "mediump vec2 " : "vec3 ") + n + ";");
    const size_t copy = s.find(" ropsim_c_" + n + ";\n#define " + n + " ropsim_c_" + n + "\n#define ropsim_has_" + n);
    ASSERT_NE(decl, std::string::npos) << n << " in\n" << s;
    ASSERT_NE(copy, std::string::npos) << n << " in\n" << s;
    EXPECT_LT(decl, copy) << n;
    EXPECT_LT(copy, s.find("#endif", decl)) << n << ": the copy is in the declaration's branch";
    // The fill, guarded.
    EXPECT_NE(s.find("#ifdef ropsim_has_" + n + "\n  ropsim_c_" + n + " = ropsim_moved ? "), std::string::npos)
        << n << " in\n"
        << s;
  }
  // An input that nothing reads gets no copy: the wrapper's read would make
  // it used, and it may have no vertex output to link with.
  const Rewritten unused = instrument_fragment_shader(
      "#version 150\nin vec3 var_ColorAmbient;\nin vec2 uv;\nout vec4 o;\nvoid main() { o = vec4(uv, 0.0, 1.0); }\n",
      GlslProfile::kCompatibility, 3);
  EXPECT_EQ(unused.source.find("ropsim_c_var_ColorAmbient"), std::string::npos) << unused.source;
  EXPECT_NE(unused.source.find("#define uv ropsim_c_uv"), std::string::npos) << unused.source;
  // The centroid declaration is left as it is.
  EXPECT_NE(s.find("centroid varying vec2 varTexCoord;\n#endif"), std::string::npos) << s;
}

}  // namespace
}  // namespace ropsim::glcapture
