// The GL capture's plain-C++ rules (traces/glcapture/fragment_order.h,
// glsl_rewrite.h; docs/capture.md "Capturing a GL frame"): the per-pass
// sample offset, the fragments of a draw's nodes in API order, and the
// shader rewrite. No GL context needed.
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

// A draw's nodes as the passes leave them (glsl_rewrite.h), built by hand.
struct Nodes {
  std::vector<uint32_t> keys, state;
  std::vector<float> colour;
  std::vector<std::vector<uint32_t>> depth = std::vector<std::vector<uint32_t>>(64);

  /// A node of (part, instance, prim) at GL window pixel (x, gy) covering
  /// `coverage`: sample s's depth z + 0.01 s, kNoDepth where the node does
  /// not cover s; flags kNodeKept by default.
  void add(uint32_t part, uint32_t instance, uint32_t prim, uint16_t x, uint16_t gy, uint64_t coverage, float z,
           float red = 0.5f, uint32_t flags = kNodeKept) {
    keys.insert(keys.end(), {prim, instance, part, kNoNode});
    state.push_back(uint32_t(x) | uint32_t(gy) << 16 | flags);
    colour.insert(colour.end(), {red, 0.25f, 0.125f, 0.5f});
    for (int s = 0; s < 64; ++s) {
      const float d = z + 0.01f * float(s);
      uint32_t u;
      std::memcpy(&u, &d, 4);
      depth[size_t(s)].push_back((coverage >> s) & 1 ? depth_word(u) : kNoDepth);
    }
  }
  size_t size() const { return keys.size() / 4; }
  /// The same nodes in another order (as llvmpipe's threads may make them).
  Nodes permuted(std::mt19937& rng) const {
    std::vector<size_t> order(size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::shuffle(order.begin(), order.end(), rng);
    Nodes o;
    for (size_t i : order) {
      o.keys.insert(o.keys.end(), keys.begin() + std::ptrdiff_t(4 * i), keys.begin() + std::ptrdiff_t(4 * i + 4));
      o.state.push_back(state[i]);
      o.colour.insert(o.colour.end(), colour.begin() + std::ptrdiff_t(4 * i),
                      colour.begin() + std::ptrdiff_t(4 * i + 4));
      for (int s = 0; s < 64; ++s) o.depth[size_t(s)].push_back(depth[size_t(s)][i]);
    }
    return o;
  }
  NodeView view() const {
    NodeView v;
    v.count = size();
    v.spp = 64;
    v.keys = keys.data();
    v.state = state.data();
    v.colour = colour.data();
    for (int s = 0; s < 64; ++s) v.depth[size_t(s)] = depth[size_t(s)].data();
    return v;
  }
};

/// A fragment's depths.
std::vector<float> depths(const CapturedDraw& d, size_t i) {
  const size_t n = size_t(__builtin_popcountll(d.fragments[i].coverage));
  return std::vector<float>(d.z.data() + d.fragments[i].z_first, d.z.data() + d.fragments[i].z_first + n);
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

TEST(GlCaptureOrder, NodesFlipRowsAndRefusePixelsOutsideAndDepthsOutsideZeroOne) {
  Nodes n;
  n.add(0, 2, 7, 5, 0, 0b1, 0.25f);
  n.add(0, 0, 8, 6, 9, 0b1, 0.5f);
  CapturedDraw out;
  ASSERT_EQ(build_fragments(n.view(), 3, {{0}}, true, 16, 10, out), "");
  ASSERT_EQ(out.fragments.size(), 2u);
  EXPECT_EQ(out.fragments[0].x, 6);
  EXPECT_EQ(out.fragments[0].y, 0);  // GL row 9 of 10 is the top: trace row 0
  EXPECT_EQ(out.fragments[1].x, 5);
  EXPECT_EQ(out.fragments[1].y, 9);
  EXPECT_EQ(out.fragments[1].draw_id, 3u);
  EXPECT_EQ(depths(out, 1), std::vector<float>{0.25f});
  n.state[1] = 6u | (10u << 16) | kNodeKept;  // row 10 of a 10-row target
  EXPECT_NE(build_fragments(n.view(), 0, {{0}}, true, 16, 10, out).find("outside the 16x10 target"), std::string::npos);
  n.state[1] = 6u | (9u << 16) | kNodeKept;
  const float far = 1.5f;
  uint32_t far_bits;
  std::memcpy(&far_bits, &far, 4);
  n.depth[0][1] = depth_word(far_bits);
  EXPECT_NE(build_fragments(n.view(), 0, {{0}}, true, 16, 10, out).find("not in [0, 1]"), std::string::npos);
}

// Fragments in (part, instance, primitive, row, column) order, one a node,
// and the same bytes whatever order the nodes were made in (llvmpipe's
// threads); more than 2^18 nodes split the work over threads.
TEST(GlCaptureOrder, FragmentsComeInApiOrderWhateverTheNodeOrder) {
  for (int big : {0, 1}) {
    Nodes base;
    const uint16_t side = big ? 300 : 3;
    for (uint32_t part = 0; part < 2; ++part)
      for (uint32_t inst = 0; inst < 2; ++inst)
        for (uint32_t prim = 0; prim < 3; ++prim)
          for (uint16_t y = 0; y < side; ++y)
            for (uint16_t x = 0; x < side; ++x)
              if ((x + y + prim) % 3 != 0)
                base.add(part, inst, prim, x, y, uint64_t(x * 7 + y + prim) & 0xF, 0.01f * float(prim));
    CapturedDraw expected;
    ASSERT_EQ(build_fragments(base.view(), 7, {{3}, {3}}, true, side, side, expected), "");
    ASSERT_FALSE(expected.fragments.size() == 0);
    for (size_t i = 1; i < expected.fragments.size(); ++i) {
      const auto& a = expected.fragments[i - 1];
      const auto& b = expected.fragments[i];
      ASSERT_TRUE(std::make_tuple(a.prim_id, a.y, a.x) < std::make_tuple(b.prim_id, b.y, b.x)) << "fragment " << i;
    }
    for (size_t i = 0; i < expected.fragments.size(); ++i) {
      const auto& f = expected.fragments[i];
      ASSERT_EQ(f.draw_id, 7u);
      ASSERT_NE(f.coverage, 0u);
      const std::vector<float> z = depths(expected, i);
      size_t k = 0;
      for (uint64_t m = f.coverage; m; m &= m - 1, ++k)
        ASSERT_FLOAT_EQ(z[k], 0.01f * float(f.prim_id % 3) + 0.01f * float(__builtin_ctzll(m)));
    }
    std::mt19937 rng(12345);
    for (int trial = 0; trial < 3; ++trial) {
      CapturedDraw got;
      ASSERT_EQ(build_fragments(base.permuted(rng).view(), 7, {{3}, {3}}, true, side, side, got), "");
      ASSERT_EQ(got.fragments.size(), expected.fragments.size());
      ASSERT_EQ(got.z.size(), expected.z.size());
      ASSERT_EQ(
          std::memcmp(got.fragments.data(), expected.fragments.data(), got.fragments.size() * sizeof(CapturedFragment)),
          0);
      ASSERT_EQ(std::memcmp(got.z.data(), expected.z.data(), got.z.size() * sizeof(float)), 0);
    }
    // The capture's records: those fragments encoded as the trace's, in the
    // same order, whatever the nodes' order.
    TraceHeader h;
    h.width = h.height = side;
    h.spp = 16;
    h.depth_mode = DepthMode::kPerSample;
    h.color_format = ColorFormat::kRgbF32;
    std::vector<uint8_t> want;
    for (const CapturedFragment& f : expected.fragments) {
      uint8_t b[kMaxFragmentRecordBytes];
      std::string err;
      const size_t n = encode_fragment_record(h, to_trace_fragment(f, expected.z.data()), b, err);
      ASSERT_EQ(err, "");
      want.insert(want.end(), b, b + n);
    }
    // The second and third builds reuse the first's scratch, and give the
    // records to a sink a run at a time.
    BuildScratch scratch;
    for (int trial = 0; trial < 3; ++trial) {
      EncodedDraw records;
      const Nodes nodes = trial ? base.permuted(rng) : base;
      if (trial == 0) {
        ASSERT_EQ(build_records(nodes.view(), 7, {{3}, {3}}, true, h, records), "");
      } else {
        std::vector<uint8_t> got;
        size_t runs_count = 0;
        ASSERT_EQ(build_records(
                      nodes.view(), 7, {{3}, {3}}, true, h, scratch,
                      [&](const uint8_t* r, size_t bytes, size_t count) {
                        got.insert(got.end(), r, r + bytes);
                        runs_count += count;
                        return std::string();
                      },
                      records),
                  "");
        EXPECT_EQ(runs_count, records.count);
        records.bytes = LargeArray<uint8_t>(got.size());
        std::memcpy(records.bytes.data(), got.data(), got.size());
      }
      EXPECT_EQ(records.count, expected.fragments.size());
      EXPECT_EQ(records.covered_samples, expected.z.size());
      ASSERT_EQ(records.size, want.size());
      EXPECT_EQ(std::memcmp(records.bytes.data(), want.data(), want.size()), 0);
    }
  }
}

// A node makes a fragment when its shaded invocation kept it (kNodeKept) and
// it covers a sample: a discarded one (not kept) and a centre-only one
// (kept, no coverage) make none.
TEST(GlCaptureOrder, OnlyKeptNodesThatCoverASampleAreFragments) {
  Nodes n;
  n.add(0, 0, 0, 1, 1, 0b110, 0.5f, 0.9f, kNodeCentre | kNodeKept);
  n.add(0, 0, 0, 2, 1, 0b1001, 0.5f, 0.35f);
  n.add(0, 0, 0, 3, 1, 0, 0.5f, 0.8f, kNodeCentre | kNodeKept);  // centre only
  n.add(0, 0, 0, 4, 1, 0b1111, 0.5f, 0.7f, kNodeCentre);         // discarded
  CapturedDraw out;
  ASSERT_EQ(build_fragments(n.view(), 0, {{1}}, true, 8, 8, out), "");
  ASSERT_EQ(out.fragments.size(), 2u);
  EXPECT_EQ(out.fragments[0].x, 1);
  EXPECT_EQ(out.fragments[0].coverage, 0b110u);
  EXPECT_EQ(depths(out, 0), (std::vector<float>{0.51f, 0.52f}));
  EXPECT_FLOAT_EQ(out.fragments[0].rgba[0], 0.9f);
  EXPECT_EQ(out.fragments[1].x, 2);
  EXPECT_EQ(out.fragments[1].coverage, 0b1001u);
  EXPECT_FLOAT_EQ(out.fragments[1].rgba[0], 0.35f);
}

// prim_id = the earlier parts' primitives + instance * primitives per
// instance + gl_PrimitiveID; the nodes raise a count the call understated.
TEST(GlCaptureOrder, PrimitiveIdsNumberInstancesAndPartsOneAfterAnother) {
  Nodes n;
  n.add(0, 1, 2, 0, 0, 1, 0.5f);
  n.add(1, 0, 0, 0, 0, 1, 0.5f);
  n.add(1, 2, 4, 0, 0, 1, 0.5f);
  CapturedDraw out;
  // Part 0: 3 primitives an instance, 2 instances (0..5); part 1: the call
  // says 2 an instance, the nodes show primitive 4, so 5, 3 instances.
  ASSERT_EQ(build_fragments(n.view(), 0, {{3}, {2}}, true, 1, 1, out), "");
  ASSERT_EQ(out.fragments.size(), 3u);
  EXPECT_EQ(out.fragments[0].prim_id, 1u * 3 + 2);
  EXPECT_EQ(out.fragments[1].prim_id, 6u + 0);
  EXPECT_EQ(out.fragments[2].prim_id, 6u + 2 * 5 + 4);
  Nodes big;
  big.add(0, 0x10000, 0xFFFF, 0, 0, 1, 0.5f);
  EXPECT_NE(build_fragments(big.view(), 3, {{0x10000}}, true, 1, 1, out).find("32-bit"), std::string::npos);
}

TEST(GlCaptureOrder, ColourIsClampedToWhatTheTargetAndTheTraceHold) {
  Nodes n;
  n.add(0, 0, 0, 0, 0, 1, 0.5f);
  std::copy_n(std::array<float, 4>{1.5f, -0.5f, std::nanf(""), 1.25f}.begin(), 4, n.colour.begin());
  CapturedDraw unorm, flt;
  ASSERT_EQ(build_fragments(n.view(), 0, {{1}}, true, 1, 1, unorm), "");
  ASSERT_EQ(build_fragments(n.view(), 0, {{1}}, false, 1, 1, flt), "");
  EXPECT_EQ(unorm.fragments[0].rgba, (std::array<float, 4>{1.0f, 0.0f, 0.0f, 1.0f}));
  EXPECT_EQ(flt.fragments[0].rgba, (std::array<float, 4>{1.5f, 0.0f, 0.0f, 1.0f}));
  const Fragment f = to_trace_fragment(unorm.fragments[0], unorm.z.data());
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
  EXPECT_EQ(fs.source.find("early_fragment_tests"), std::string::npos);
  // The shading passes' twin tests before the shader; the sample passes'
  // coverage shader runs none of the application's and walks the list
  // through texel fetches on the units given.
  const Rewritten early =
      instrument_fragment_shader("void main() { gl_FragColor = vec4(1.0); }", GlslProfile::kCore, 5, {}, true);
  EXPECT_NE(early.source.find("layout(early_fragment_tests) in;"), std::string::npos);
  const Rewritten cov = coverage_fragment_shader(GlslProfile::kCompatibility, 5, 94);
  ASSERT_EQ(cov.error, "");
  EXPECT_EQ(cov.source.find("#version 450 compatibility"), 0u);
  for (const char* want :
       {"binding = 9) writeonly buffer RopsimDepth", "layout(binding = 94) uniform usamplerBuffer",
        "layout(binding = 95) uniform usamplerBuffer", "texelFetch(ropsim_keys", "if (found) discard;"})
    EXPECT_NE(cov.source.find(want), std::string::npos) << want << " in\n" << cov.source;
  EXPECT_EQ(cov.source.find("ropsim_app_main"), std::string::npos);
  EXPECT_EQ(cov.source.find("atomic"), std::string::npos);
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
