// The fixed-function emulation (traces/glcapture/ff_program.h) against Mesa's
// own fixed-function pipeline: in an OSMesa compatibility context (llvmpipe,
// no X), each test sets fixed-function state, draws a lit, coloured,
// textured grid with it, reads the state back with read_fixed_function_state,
// draws the same grid again with the generated program, and compares the two
// images: >= 99.9 % of pixels within 1/255 on every channel (a test that
// needs more says so and why). Each test also checks that its feature changes
// the image, so a program that ignored it would fail the comparison.
// osmesa.h (GL/gl.h) defines the types glext.h uses: keep this order.
// clang-format off
#include <GL/osmesa.h>
#include <GL/glext.h>
// clang-format on
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <string>
#include <vector>

#include "traces/glcapture/ff_program.h"

namespace {

using namespace ropsim::glcapture;

constexpr int kW = 96, kH = 96;

struct Image {
  std::vector<unsigned char> rgba;
};

struct Comparison {
  double within = 0;  ///< fraction of pixels whose 4 channels all differ by <= the tolerance
  int max_diff = 0;   ///< the largest channel difference (8-bit units)
};

Comparison compare(const Image& a, const Image& b, int tolerance) {
  Comparison c;
  size_t ok = 0;
  const size_t n = a.rgba.size() / 4;
  for (size_t p = 0; p < n; ++p) {
    int d = 0;
    for (size_t k = 0; k < 4; ++k) d = std::max(d, std::abs(int(a.rgba[4 * p + k]) - int(b.rgba[4 * p + k])));
    c.max_diff = std::max(c.max_diff, d);
    ok += d <= tolerance;
  }
  c.within = n ? double(ok) / double(n) : 0;
  return c;
}

/// Fraction of pixels of `a` that are not the clear colour (pixel 0 of `clear`).
double covered(const Image& a, const Image& clear) {
  size_t n = 0;
  for (size_t p = 0; p < a.rgba.size(); p += 4)
    n += !std::equal(a.rgba.begin() + long(p), a.rgba.begin() + long(p) + 4, clear.rgba.begin());
  return double(n) / double(a.rgba.size() / 4);
}

/// A grid of 14 x 14 quads (two triangles each) on a bumpy surface, with per
/// vertex colour (alpha 0.2 .. 1), normal, two texture coordinate sets and a
/// fog coordinate, as client arrays.
struct Grid {
  std::vector<float> position, color, secondary, normal, tc0, tc1, fog;
  Grid() {
    const int n = 14;
    auto vertex = [&](int i, int j) {
      const float u = float(i) / n, v = float(j) / n;
      const float x = -1.5f + 3 * u, y = -1.5f + 3 * v;
      const float z = 0.3f * std::sin(2 * x) * std::cos(2 * y);
      // Normal of z = f(x, y): (-df/dx, -df/dy, 1).
      const float dx = 0.6f * std::cos(2 * x) * std::cos(2 * y), dy = -0.6f * std::sin(2 * x) * std::sin(2 * y);
      position.insert(position.end(), {x, y, z});
      color.insert(color.end(), {u, v, 1 - u * v, 0.2f + 0.8f * (u + v) / 2});
      secondary.insert(secondary.end(), {0.3f * v, 0.2f * u, 0.1f});
      normal.insert(normal.end(), {-dx, -dy, 1});
      tc0.insert(tc0.end(), {2 * u, 2 * v});
      tc1.insert(tc1.end(), {3 * v, 1.5f * u});
      fog.push_back(1 + 6 * u);
    };
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        vertex(i, j), vertex(i + 1, j), vertex(i + 1, j + 1);
        vertex(i, j), vertex(i + 1, j + 1), vertex(i, j + 1);
      }
  }
  GLsizei count() const { return GLsizei(position.size() / 3); }
};

class FfProgram : public ::testing::Test {
 protected:
  void SetUp() override {
    setenv("LP_NUM_THREADS", "2", 0);  // the machine is shared; respect a caller's setting
    const int attribs[] = {OSMESA_FORMAT,
                           OSMESA_RGBA,
                           OSMESA_DEPTH_BITS,
                           0,
                           OSMESA_STENCIL_BITS,
                           0,
                           OSMESA_PROFILE,
                           OSMESA_COMPAT_PROFILE,
                           0};
    ctx_ = OSMesaCreateContextAttribs(attribs, nullptr);
    ASSERT_NE(ctx_, nullptr) << "OSMesa cannot create a compatibility context";
    buffer_.resize(size_t(kW) * kH * 4);
    ASSERT_TRUE(OSMesaMakeCurrent(ctx_, buffer_.data(), GL_UNSIGNED_BYTE, kW, kH));
    load();
    getters_.GetIntegerv = &glGetIntegerv;
    getters_.GetFloatv = &glGetFloatv;
    getters_.IsEnabled = &glIsEnabled;
    getters_.GetTexEnviv = &glGetTexEnviv;
    getters_.GetTexEnvfv = &glGetTexEnvfv;
    getters_.GetLightfv = &glGetLightfv;
    getters_.GetTexParameteriv = &glGetTexParameteriv;
    getters_.GetTexLevelParameteriv = &glGetTexLevelParameteriv;
    getters_.ActiveTexture = ActiveTexture;

    glViewport(0, 0, kW, kH);
    glMatrixMode(GL_PROJECTION);
    glLoadIdentity();
    glFrustum(-1, 1, -1, 1, 2, 20);
    glMatrixMode(GL_MODELVIEW);
    glLoadIdentity();
    glTranslatef(0, 0.5f, -3.6f);
    glRotatef(-45, 1, 0, 0);
    glRotatef(20, 0, 0, 1);
  }
  void TearDown() override {
    for (GLuint t : textures_) glDeleteTextures(1, &t);
    if (ctx_) OSMesaDestroyContext(ctx_);
  }

  void load() {
    auto get = [](const char* name) {
      auto f = OSMesaGetProcAddress(name);
      if (!f) ADD_FAILURE() << "OSMesa has no " << name;
      return f;
    };
#define ROPSIM_LOAD(type, name) name = reinterpret_cast<type>(get("gl" #name));
    ROPSIM_LOAD(PFNGLCREATESHADERPROC, CreateShader)
    ROPSIM_LOAD(PFNGLSHADERSOURCEPROC, ShaderSource)
    ROPSIM_LOAD(PFNGLCOMPILESHADERPROC, CompileShader)
    ROPSIM_LOAD(PFNGLGETSHADERIVPROC, GetShaderiv)
    ROPSIM_LOAD(PFNGLGETSHADERINFOLOGPROC, GetShaderInfoLog)
    ROPSIM_LOAD(PFNGLDELETESHADERPROC, DeleteShader)
    ROPSIM_LOAD(PFNGLCREATEPROGRAMPROC, CreateProgram)
    ROPSIM_LOAD(PFNGLATTACHSHADERPROC, AttachShader)
    ROPSIM_LOAD(PFNGLLINKPROGRAMPROC, LinkProgram)
    ROPSIM_LOAD(PFNGLGETPROGRAMIVPROC, GetProgramiv)
    ROPSIM_LOAD(PFNGLGETPROGRAMINFOLOGPROC, GetProgramInfoLog)
    ROPSIM_LOAD(PFNGLUSEPROGRAMPROC, UseProgram)
    ROPSIM_LOAD(PFNGLDELETEPROGRAMPROC, DeleteProgram)
    ROPSIM_LOAD(PFNGLACTIVETEXTUREPROC, ActiveTexture)
    ClientActiveTexture = reinterpret_cast<PFNGLCLIENTACTIVETEXTUREARBPROC>(get("glClientActiveTexture"));
    ROPSIM_LOAD(PFNGLSECONDARYCOLORPOINTERPROC, SecondaryColorPointer)
    ROPSIM_LOAD(PFNGLFOGCOORDPOINTERPROC, FogCoordPointer)
#undef ROPSIM_LOAD
  }

  /// Compiles and links the program; 0 (and a failure naming the log and the
  /// source) when it does not compile or link.
  GLuint link(const GlslProgram& p) {
    GLuint prog = CreateProgram();
    for (auto [type, src] : {std::pair<GLenum, const std::string*>{GL_VERTEX_SHADER, &p.vertex},
                             std::pair<GLenum, const std::string*>{GL_FRAGMENT_SHADER, &p.fragment}}) {
      GLuint s = CreateShader(type);
      const char* text = src->c_str();
      ShaderSource(s, 1, &text, nullptr);
      CompileShader(s);
      GLint ok = 0;
      GetShaderiv(s, GL_COMPILE_STATUS, &ok);
      if (!ok) {
        char log[4096] = {};
        GetShaderInfoLog(s, sizeof log, nullptr, log);
        ADD_FAILURE() << "the generated shader does not compile: " << log << "\n" << *src;
        DeleteShader(s);
        DeleteProgram(prog);
        return 0;
      }
      AttachShader(prog, s);
      DeleteShader(s);
    }
    LinkProgram(prog);
    GLint ok = 0;
    GetProgramiv(prog, GL_LINK_STATUS, &ok);
    if (!ok) {
      char log[4096] = {};
      GetProgramInfoLog(prog, sizeof log, nullptr, log);
      ADD_FAILURE() << "the generated program does not link: " << log << "\n" << p.vertex << p.fragment;
      DeleteProgram(prog);
      return 0;
    }
    return prog;
  }

  FixedFunctionState read() {
    const FixedFunctionState s = read_fixed_function_state(getters_);
    EXPECT_EQ(glGetError(), GLenum(GL_NO_ERROR)) << "reading the state raised a GL error";
    return s;
  }

  /// The grid as client arrays (both texture coordinate sets, the secondary
  /// colour and the fog coordinate are always given).
  void draw_grid() {
    glEnableClientState(GL_VERTEX_ARRAY);
    glVertexPointer(3, GL_FLOAT, 0, grid_.position.data());
    glEnableClientState(GL_COLOR_ARRAY);
    glColorPointer(4, GL_FLOAT, 0, grid_.color.data());
    glEnableClientState(GL_NORMAL_ARRAY);
    glNormalPointer(GL_FLOAT, 0, grid_.normal.data());
    glEnableClientState(GL_SECONDARY_COLOR_ARRAY);
    SecondaryColorPointer(3, GL_FLOAT, 0, grid_.secondary.data());
    glEnableClientState(GL_FOG_COORD_ARRAY);
    FogCoordPointer(GL_FLOAT, 0, grid_.fog.data());
    for (int u = 0; u < 2; ++u) {
      ClientActiveTexture(GL_TEXTURE0 + GLenum(u));
      glEnableClientState(GL_TEXTURE_COORD_ARRAY);
      glTexCoordPointer(2, GL_FLOAT, 0, (u ? grid_.tc1 : grid_.tc0).data());
    }
    glDrawArrays(GL_TRIANGLES, 0, grid_.count());
  }

  /// Draws with the current fixed-function state (program == nullptr) or
  /// with the generated program for `state` (the alpha test of the GL state
  /// is turned off around that draw: it applies after a fragment shader in a
  /// compatibility context, and the program's discard must do its work).
  Image render(const FixedFunctionState* state, const std::function<void()>& draw = {}) {
    glClearColor(0.2f, 0.3f, 0.4f, 1);
    glClear(GL_COLOR_BUFFER_BIT);
    if (clear_.rgba.empty()) {
      clear_.rgba.resize(4);
      glReadPixels(0, 0, 1, 1, GL_RGBA, GL_UNSIGNED_BYTE, clear_.rgba.data());
    }
    GLuint prog = 0;
    const bool alpha_test = glIsEnabled(GL_ALPHA_TEST);
    if (state) {
      prog = link(fixed_function_program(*state));
      if (!prog) return {};
      UseProgram(prog);
      glDisable(GL_ALPHA_TEST);
    }
    if (draw)
      draw();
    else
      draw_grid();
    glFinish();
    Image img;
    img.rgba.resize(size_t(kW) * kH * 4);
    glReadPixels(0, 0, kW, kH, GL_RGBA, GL_UNSIGNED_BYTE, img.rgba.data());
    if (prog) {
      UseProgram(0);
      DeleteProgram(prog);
      if (alpha_test) glEnable(GL_ALPHA_TEST);
    }
    EXPECT_EQ(glGetError(), GLenum(GL_NO_ERROR));
    return img;
  }

  /// Renders with the fixed-function pipeline and with the program of the
  /// state read back; expects >= 99.9 % of pixels within `tolerance`.
  /// Returns the fixed-function image.
  Image expect_match(const std::string& what, int tolerance = 1, const std::function<void()>& draw = {}) {
    SCOPED_TRACE(what);
    const FixedFunctionState s = read();
    EXPECT_EQ(unsupported_reason(s), "") << "the state must be inside the subset";
    const Image ff = render(nullptr, draw);
    const Image prog = render(&s, draw);
    if (prog.rgba.empty()) return ff;
    const Comparison c = compare(ff, prog, tolerance);
    const Comparison exact = compare(ff, prog, 0), one = compare(ff, prog, 1);
    std::cout << "  " << what << ": equal " << exact.within * 100 << " %, within 1/255 " << one.within * 100
              << " %, max diff " << c.max_diff << "/255\n";
    EXPECT_GE(c.within, 0.999) << "pixels within " << tolerance << "/255: " << c.within * 100 << " %, max diff "
                               << c.max_diff;
    EXPECT_GT(covered(ff, clear_), 0.4) << "the grid must cover a good part of the image";
    return ff;
  }

  /// An 8 x 8 texture of `format` (GL_ALPHA ... GL_RGBA), a smooth pattern in
  /// every component, linear filtering, repeat, no mipmaps, on the active unit.
  GLuint texture(GLenum internal_format, GLenum format, int seed = 0) {
    const int comps = format == GL_RGBA ? 4 : format == GL_RGB ? 3 : format == GL_LUMINANCE_ALPHA ? 2 : 1;
    std::vector<unsigned char> data;
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x)
        for (int c = 0; c < comps; ++c)
          data.push_back(static_cast<unsigned char>((x * 29 + y * 17 + c * 83 + seed * 41 + (x ^ y) * 7 * c) % 256));
    GLuint t = 0;
    glGenTextures(1, &t);
    textures_.push_back(t);
    glBindTexture(GL_TEXTURE_2D, t);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage2D(GL_TEXTURE_2D, 0, GLint(internal_format), 8, 8, 0, format, GL_UNSIGNED_BYTE, data.data());
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_REPEAT);
    return t;
  }

  void lights_and_material() {
    glPushMatrix();
    glLoadIdentity();  // light positions in eye coordinates
    const float dir[] = {0.3f, 0.5f, 1, 0}, white[] = {0.6f, 0.6f, 0.6f, 1}, amb0[] = {0.1f, 0.1f, 0.1f, 1};
    glLightfv(GL_LIGHT0, GL_POSITION, dir);
    glLightfv(GL_LIGHT0, GL_DIFFUSE, white);
    glLightfv(GL_LIGHT0, GL_SPECULAR, white);
    glLightfv(GL_LIGHT0, GL_AMBIENT, amb0);
    const float pos[] = {1.2f, 1.0f, -2.5f, 1}, orange[] = {0.8f, 0.5f, 0.2f, 1}, amb1[] = {0.05f, 0.02f, 0, 1};
    glLightfv(GL_LIGHT1, GL_POSITION, pos);
    glLightfv(GL_LIGHT1, GL_DIFFUSE, orange);
    glLightfv(GL_LIGHT1, GL_SPECULAR, orange);
    glLightfv(GL_LIGHT1, GL_AMBIENT, amb1);
    glLightf(GL_LIGHT1, GL_CONSTANT_ATTENUATION, 0.8f);
    glLightf(GL_LIGHT1, GL_LINEAR_ATTENUATION, 0.15f);
    glLightf(GL_LIGHT1, GL_QUADRATIC_ATTENUATION, 0.05f);
    glPopMatrix();
    material();
    glEnable(GL_LIGHTING);
    glEnable(GL_LIGHT0);
    glEnable(GL_LIGHT1);
    glEnable(GL_NORMALIZE);
  }

  /// The front and back material (GL_COLOR_MATERIAL overwrites it with the
  /// current colour while it is on).
  static void material() {
    const float ma[] = {0.3f, 0.2f, 0.25f, 1}, md[] = {0.6f, 0.7f, 0.5f, 0.8f}, ms[] = {0.6f, 0.6f, 0.6f, 1},
                me[] = {0.05f, 0.0f, 0.1f, 1}, scene[] = {0.15f, 0.15f, 0.2f, 1};
    glMaterialfv(GL_FRONT_AND_BACK, GL_AMBIENT, ma);
    glMaterialfv(GL_FRONT_AND_BACK, GL_DIFFUSE, md);
    glMaterialfv(GL_FRONT_AND_BACK, GL_SPECULAR, ms);
    glMaterialfv(GL_FRONT_AND_BACK, GL_EMISSION, me);
    glMaterialf(GL_FRONT_AND_BACK, GL_SHININESS, 24);
    glLightModelfv(GL_LIGHT_MODEL_AMBIENT, scene);
  }

  /// Expects `b` to differ from `a` on at least `fraction` of the pixels (by
  /// more than 2/255): the feature under test shows in the image.
  void expect_differs(const Image& a, const Image& b, double fraction, const std::string& what) {
    size_t grid = 0, differ = 0;
    for (size_t p = 0; p < a.rgba.size(); p += 4) {
      const bool in_a = !std::equal(a.rgba.begin() + long(p), a.rgba.begin() + long(p) + 4, clear_.rgba.begin());
      const bool in_b = !std::equal(b.rgba.begin() + long(p), b.rgba.begin() + long(p) + 4, clear_.rgba.begin());
      if (!in_a && !in_b) continue;
      ++grid;
      int d = 0;
      for (size_t k = 0; k < 4; ++k) d = std::max(d, std::abs(int(a.rgba[p + k]) - int(b.rgba[p + k])));
      differ += d > 2;
    }
    EXPECT_GE(double(differ), fraction * double(grid))
        << what << " must change the image: " << differ << " of " << grid << " grid pixels differ by more than 2/255";
  }

  /// A GL_COMBINE environment: every parameter, GL's initial values unless set.
  struct Combine {
    GLenum rgb = GL_MODULATE, alpha = GL_MODULATE;
    GLenum src_rgb[3] = {GL_TEXTURE, GL_PREVIOUS, GL_CONSTANT};
    GLenum op_rgb[3] = {GL_SRC_COLOR, GL_SRC_COLOR, GL_SRC_ALPHA};
    GLenum src_alpha[3] = {GL_TEXTURE, GL_PREVIOUS, GL_CONSTANT};
    GLenum op_alpha[3] = {GL_SRC_ALPHA, GL_SRC_ALPHA, GL_SRC_ALPHA};
    float rgb_scale = 1, alpha_scale = 1;
  };

  /// Sets GL_TEXTURE_ENV_MODE GL_COMBINE and all of `c` on the active unit.
  static void set_combine(const Combine& c) {
    glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_COMBINE);
    glTexEnvi(GL_TEXTURE_ENV, GL_COMBINE_RGB, GLint(c.rgb));
    glTexEnvi(GL_TEXTURE_ENV, GL_COMBINE_ALPHA, GLint(c.alpha));
    const GLenum src_rgb[] = {GL_SRC0_RGB, GL_SRC1_RGB, GL_SRC2_RGB};
    const GLenum src_alpha[] = {GL_SRC0_ALPHA, GL_SRC1_ALPHA, GL_SRC2_ALPHA};
    const GLenum op_rgb[] = {GL_OPERAND0_RGB, GL_OPERAND1_RGB, GL_OPERAND2_RGB};
    const GLenum op_alpha[] = {GL_OPERAND0_ALPHA, GL_OPERAND1_ALPHA, GL_OPERAND2_ALPHA};
    for (int i = 0; i < 3; ++i) {
      glTexEnvi(GL_TEXTURE_ENV, src_rgb[i], GLint(c.src_rgb[i]));
      glTexEnvi(GL_TEXTURE_ENV, src_alpha[i], GLint(c.src_alpha[i]));
      glTexEnvi(GL_TEXTURE_ENV, op_rgb[i], GLint(c.op_rgb[i]));
      glTexEnvi(GL_TEXTURE_ENV, op_alpha[i], GLint(c.op_alpha[i]));
    }
    glTexEnvf(GL_TEXTURE_ENV, GL_RGB_SCALE, c.rgb_scale);
    glTexEnvf(GL_TEXTURE_ENV, GL_ALPHA_SCALE, c.alpha_scale);
  }

  OSMesaContext ctx_ = nullptr;
  std::vector<unsigned char> buffer_;
  std::vector<GLuint> textures_;
  Image clear_;  ///< the clear colour as read back (one pixel)
  GlGetters getters_;
  Grid grid_;

  PFNGLCREATESHADERPROC CreateShader = nullptr;
  PFNGLSHADERSOURCEPROC ShaderSource = nullptr;
  PFNGLCOMPILESHADERPROC CompileShader = nullptr;
  PFNGLGETSHADERIVPROC GetShaderiv = nullptr;
  PFNGLGETSHADERINFOLOGPROC GetShaderInfoLog = nullptr;
  PFNGLDELETESHADERPROC DeleteShader = nullptr;
  PFNGLCREATEPROGRAMPROC CreateProgram = nullptr;
  PFNGLATTACHSHADERPROC AttachShader = nullptr;
  PFNGLLINKPROGRAMPROC LinkProgram = nullptr;
  PFNGLGETPROGRAMIVPROC GetProgramiv = nullptr;
  PFNGLGETPROGRAMINFOLOGPROC GetProgramInfoLog = nullptr;
  PFNGLUSEPROGRAMPROC UseProgram = nullptr;
  PFNGLDELETEPROGRAMPROC DeleteProgram = nullptr;
  PFNGLACTIVETEXTUREPROC ActiveTexture = nullptr;
  PFNGLCLIENTACTIVETEXTUREARBPROC ClientActiveTexture = nullptr;
  PFNGLSECONDARYCOLORPOINTERPROC SecondaryColorPointer = nullptr;
  PFNGLFOGCOORDPOINTERPROC FogCoordPointer = nullptr;
};

// Vertex colour from a colour array, smooth and flat, with and without the
// colour sum, with a user clip plane; and from glColor in immediate mode.
TEST_F(FfProgram, VertexColourMatchesFixedFunction) {
  const Image smooth = expect_match("smooth, colour array");
  glShadeModel(GL_FLAT);
  EXPECT_TRUE(read().flat_shading);
  const Image flat = expect_match("flat, colour array");
  expect_differs(smooth, flat, 0.5, "glShadeModel(GL_FLAT)");
  glShadeModel(GL_SMOOTH);
  glEnable(GL_COLOR_SUM);
  EXPECT_TRUE(read().color_sum);
  const Image sum = expect_match("smooth, colour sum");
  expect_differs(smooth, sum, 0.5, "GL_COLOR_SUM");
  glDisable(GL_COLOR_SUM);
  // A user clip plane (in eye coordinates) through the middle of the grid.
  glPushMatrix();
  glLoadIdentity();
  const double plane[] = {1, 0.4, 0, 0.1};
  glClipPlane(GL_CLIP_PLANE0, plane);
  glPopMatrix();
  glEnable(GL_CLIP_PLANE0);
  EXPECT_EQ(read().clip_planes, 1u);
  const Image clipped = render(nullptr);
  const FixedFunctionState s = read();
  const Comparison c = compare(clipped, render(&s), 1);
  EXPECT_GE(c.within, 0.999) << "GL_CLIP_PLANE0: max diff " << c.max_diff;
  expect_differs(smooth, clipped, 0.3, "GL_CLIP_PLANE0");
  glDisable(GL_CLIP_PLANE0);
  expect_match("immediate mode", 1, [] {
    glBegin(GL_TRIANGLES);
    for (int t = 0; t < 12; ++t) {
      const float a = float(t) * 0.5236f;
      glColor4f(1, 0.5f + 0.5f * std::cos(a), 0.2f, 1);
      glVertex3f(0, 0, 0);
      glColor4f(0.1f, 0.9f, 0.5f + 0.5f * std::sin(a), 1);
      glVertex3f(2.6f * std::cos(a), 2.6f * std::sin(a), 0);
      glColor4f(0.3f, 0.2f, 0.9f, 1);
      glVertex3f(2.6f * std::cos(a + 0.5236f), 2.6f * std::sin(a + 0.5236f), 0.3f);
    }
    glEnd();
  });
}

// One unit, GL_MODULATE, with an RGBA texture.
TEST_F(FfProgram, TextureModulateMatchesFixedFunction) {
  const Image plain = expect_match("no texture");
  texture(GL_RGBA8, GL_RGBA);
  glEnable(GL_TEXTURE_2D);
  glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_MODULATE);
  const FixedFunctionState s = read();
  EXPECT_TRUE(s.units[0].active());
  EXPECT_EQ(s.units[0].env, TexEnvMode::kModulate);
  EXPECT_EQ(s.units[0].base, TexBaseFormat::kRgba);
  EXPECT_FALSE(s.units[1].active());
  const Image tex = expect_match("GL_MODULATE, GL_RGBA8");
  expect_differs(plain, tex, 0.5, "the texture");
}

// GL_REPLACE, GL_DECAL, GL_ADD and GL_BLEND on one unit, with textures of
// every base format each mode defines (DECAL: RGB and RGBA only).
TEST_F(FfProgram, TextureEnvironmentModesMatchFixedFunction) {
  const float env_color[] = {0.9f, 0.3f, 0.6f, 0.4f};
  glTexEnvfv(GL_TEXTURE_ENV, GL_TEXTURE_ENV_COLOR, env_color);
  glEnable(GL_TEXTURE_2D);
  struct Format {
    GLenum internal, format;
    TexBaseFormat base;
    const char* name;
  };
  const Format formats[] = {
      {GL_RGBA8, GL_RGBA, TexBaseFormat::kRgba, "RGBA8"},
      {GL_RGB8, GL_RGB, TexBaseFormat::kRgb, "RGB8"},
      {GL_LUMINANCE8, GL_LUMINANCE, TexBaseFormat::kLuminance, "LUMINANCE8"},
      {GL_LUMINANCE8_ALPHA8, GL_LUMINANCE_ALPHA, TexBaseFormat::kLuminanceAlpha, "LUMINANCE8_ALPHA8"},
      {GL_INTENSITY8, GL_LUMINANCE, TexBaseFormat::kIntensity, "INTENSITY8"},
      {GL_ALPHA8, GL_ALPHA, TexBaseFormat::kAlpha, "ALPHA8"}};
  const std::pair<GLenum, const char*> modes[] = {
      {GL_REPLACE, "REPLACE"}, {GL_DECAL, "DECAL"}, {GL_ADD, "ADD"}, {GL_BLEND, "BLEND"}, {GL_MODULATE, "MODULATE"}};
  for (const Format& f : formats) {
    texture(f.internal, f.format);
    EXPECT_EQ(read().units[0].base, f.base) << f.name;
    std::vector<Image> images;
    for (auto [mode, name] : modes) {
      if (mode == GL_DECAL && f.base != TexBaseFormat::kRgb && f.base != TexBaseFormat::kRgba) continue;
      glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GLint(mode));
      images.push_back(expect_match(std::string("GL_") + name + ", " + f.name));
    }
    // The modes give different images (ALPHA's colour is the same in all).
    if (f.base != TexBaseFormat::kAlpha) expect_differs(images[0], images[images.size() - 2], 0.3, f.name);
  }
}

// Two units: unit 0 MODULATE with an RGBA texture, unit 1 ADD or DECAL with
// a second texture, its coordinates through a texture matrix.
TEST_F(FfProgram, TwoTextureUnitsMatchFixedFunction) {
  texture(GL_RGBA8, GL_RGBA);
  glEnable(GL_TEXTURE_2D);
  glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_MODULATE);
  const Image one = expect_match("unit 0 only");
  ActiveTexture(GL_TEXTURE1);
  texture(GL_RGB8, GL_RGB, 3);
  glEnable(GL_TEXTURE_2D);
  glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_ADD);
  glMatrixMode(GL_TEXTURE);
  glLoadIdentity();
  glRotatef(30, 0, 0, 1);
  glScalef(0.7f, 1.3f, 1);
  glMatrixMode(GL_MODELVIEW);
  ActiveTexture(GL_TEXTURE0);
  const FixedFunctionState s = read();
  EXPECT_TRUE(s.units[0].active() && s.units[1].active());
  EXPECT_EQ(s.units[1].env, TexEnvMode::kAdd);
  const Image two = expect_match("unit 1 GL_ADD, texture matrix");
  expect_differs(one, two, 0.5, "texture unit 1");
  ActiveTexture(GL_TEXTURE1);
  glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_DECAL);
  ActiveTexture(GL_TEXTURE0);
  expect_match("unit 1 GL_DECAL");
  GLint unit = 0;
  glGetIntegerv(GL_ACTIVE_TEXTURE, &unit);
  EXPECT_EQ(unit, GL_TEXTURE0) << "read_fixed_function_state must restore the active texture unit";
}

// GL_COMBINE on one unit: each RGB function (REPLACE, MODULATE, ADD,
// ADD_SIGNED, INTERPOLATE, SUBTRACT, DOT3_RGB, DOT3_RGBA) and ALPHA function,
// each source (TEXTURE, CONSTANT, PRIMARY_COLOR, PREVIOUS) and operand, and
// RGB_SCALE / ALPHA_SCALE 1, 2 and 4; Irrlicht's 2D setup (MODULATE of TEXTURE
// and PRIMARY_COLOR for RGB and ALPHA) on textures of every base format (the
// texture source components per base format).
TEST_F(FfProgram, TextureCombineMatchesFixedFunction) {
  const float env_color[] = {0.9f, 0.3f, 0.6f, 0.4f};
  glTexEnvfv(GL_TEXTURE_ENV, GL_TEXTURE_ENV_COLOR, env_color);
  texture(GL_RGBA8, GL_RGBA);
  glEnable(GL_TEXTURE_2D);
  glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_MODULATE);
  const Image modulate = expect_match("GL_MODULATE (not combine)");

  // Irrlicht's 2D images and vertex-alpha materials.
  Combine irrlicht;
  irrlicht.src_rgb[1] = GL_PRIMARY_COLOR;
  irrlicht.src_alpha[1] = GL_PRIMARY_COLOR;
  set_combine(irrlicht);
  FixedFunctionState s = read();
  EXPECT_EQ(s.units[0].env, TexEnvMode::kCombine);
  EXPECT_EQ(s.units[0].combine.rgb, CombineFunc::kModulate);
  EXPECT_EQ(s.units[0].combine.rgb_args[1].source, CombineSource::kPrimaryColor);
  EXPECT_EQ(s.units[0].combine.alpha_args[1].source, CombineSource::kPrimaryColor);
  EXPECT_EQ(s.units[0].combine.rgb_args[2], CombineState{}.rgb_args[2]) << "MODULATE does not read Arg2";
  const Image irr = expect_match("COMBINE MODULATE(TEXTURE, PRIMARY_COLOR) rgb and alpha");
  EXPECT_GE(compare(modulate, irr, 0).within, 0.999) << "the same function as GL_MODULATE on an RGBA texture";

  struct Case {
    const char* name;
    Combine c;
    double differs;  ///< the fraction of pixels that must differ from Irrlicht's setup
  };
  std::vector<Case> cases;
  auto add = [&](const char* name, double differs, const std::function<void(Combine&)>& f) {
    Combine c = irrlicht;
    f(c);
    cases.push_back({name, c, differs});
  };
  add("MODULATE(TEXTURE, PRIMARY_COLOR), RGB_SCALE 2", 0.3, [](Combine& c) { c.rgb_scale = 2; });
  add("MODULATE, RGB_SCALE 4, ALPHA_SCALE 2", 0.3, [](Combine& c) { c.rgb_scale = 4, c.alpha_scale = 2; });
  add("REPLACE(TEXTURE), REPLACE(PRIMARY_COLOR alpha)", 0.3, [](Combine& c) {
    c.rgb = GL_REPLACE, c.alpha = GL_REPLACE;
    c.src_alpha[0] = GL_PRIMARY_COLOR;
  });
  add("INTERPOLATE(TEXTURE, CONSTANT, PRIMARY_COLOR alpha)", 0.3, [](Combine& c) {
    c.rgb = c.alpha = GL_INTERPOLATE;
    c.src_rgb[1] = GL_CONSTANT, c.src_rgb[2] = GL_PRIMARY_COLOR;
    c.src_alpha[1] = GL_CONSTANT, c.src_alpha[2] = GL_PRIMARY_COLOR;
  });
  add("INTERPOLATE(CONSTANT, PREVIOUS, ONE_MINUS_SRC_COLOR of TEXTURE)", 0.3, [](Combine& c) {
    c.rgb = GL_INTERPOLATE;
    c.src_rgb[0] = GL_CONSTANT, c.src_rgb[1] = GL_PREVIOUS, c.src_rgb[2] = GL_TEXTURE;
    c.op_rgb[2] = GL_ONE_MINUS_SRC_COLOR;
  });
  add("ADD(TEXTURE, PRIMARY_COLOR)", 0.3, [](Combine& c) { c.rgb = c.alpha = GL_ADD; });
  add("ADD_SIGNED(TEXTURE, PRIMARY_COLOR), RGB_SCALE 2", 0.3, [](Combine& c) {
    c.rgb = c.alpha = GL_ADD_SIGNED;
    c.rgb_scale = 2;
  });
  add("SUBTRACT(TEXTURE, PRIMARY_COLOR), SUBTRACT(PRIMARY_COLOR, TEXTURE) alpha", 0.3, [](Combine& c) {
    c.rgb = c.alpha = GL_SUBTRACT;
    c.src_alpha[0] = GL_PRIMARY_COLOR, c.src_alpha[1] = GL_TEXTURE;
  });
  add("SUBTRACT with ONE_MINUS_SRC_COLOR, SRC_ALPHA, ONE_MINUS_SRC_ALPHA", 0.3, [](Combine& c) {
    c.rgb = GL_SUBTRACT;
    c.op_rgb[0] = GL_ONE_MINUS_SRC_COLOR, c.op_rgb[1] = GL_SRC_ALPHA;
    c.alpha = GL_ADD;
    c.op_alpha[0] = GL_ONE_MINUS_SRC_ALPHA;
  });
  add("MODULATE(TEXTURE, ONE_MINUS_SRC_ALPHA of PRIMARY_COLOR)", 0.3,
      [](Combine& c) { c.op_rgb[1] = GL_ONE_MINUS_SRC_ALPHA; });
  add("DOT3_RGB(TEXTURE, PRIMARY_COLOR)", 0.3, [](Combine& c) { c.rgb = GL_DOT3_RGB; });
  add("DOT3_RGB(TEXTURE, CONSTANT), RGB_SCALE 2, alpha REPLACE(CONSTANT)", 0.3, [](Combine& c) {
    c.rgb = GL_DOT3_RGB, c.src_rgb[1] = GL_CONSTANT, c.rgb_scale = 2;
    c.alpha = GL_REPLACE, c.src_alpha[0] = GL_CONSTANT;
  });
  add("DOT3_RGBA(TEXTURE, PRIMARY_COLOR), ALPHA_SCALE 2", 0.3, [](Combine& c) {
    c.rgb = GL_DOT3_RGBA, c.alpha_scale = 2;
    c.alpha = GL_REPLACE;  // ignored
  });
  add("DOT3_RGBA(PREVIOUS, TEXTURE), ONE_MINUS_SRC_COLOR", 0.3, [](Combine& c) {
    c.rgb = GL_DOT3_RGBA;
    c.src_rgb[0] = GL_PREVIOUS, c.src_rgb[1] = GL_TEXTURE, c.op_rgb[1] = GL_ONE_MINUS_SRC_COLOR;
  });
  add("GL_TEXTURE0 (the unit itself) for GL_TEXTURE", 0.0, [](Combine& c) { c.src_rgb[0] = GL_TEXTURE0; });
  for (const Case& k : cases) {
    set_combine(k.c);
    const Image img = expect_match(std::string("COMBINE ") + k.name);
    if (k.differs > 0) expect_differs(irr, img, k.differs, k.name);
  }
  set_combine(irrlicht);
  s = read();
  set_combine(cases.back().c);
  EXPECT_EQ(read(), s) << "GL_TEXTURE0 on unit 0 is GL_TEXTURE: the same state";

  // Irrlicht's setup, and one with every operand, on each base format.
  struct Format {
    GLenum internal, format;
    const char* name;
  };
  const Format formats[] = {{GL_RGB8, GL_RGB, "RGB8"},
                            {GL_LUMINANCE8, GL_LUMINANCE, "LUMINANCE8"},
                            {GL_LUMINANCE8_ALPHA8, GL_LUMINANCE_ALPHA, "LUMINANCE8_ALPHA8"},
                            {GL_INTENSITY8, GL_LUMINANCE, "INTENSITY8"},
                            {GL_ALPHA8, GL_ALPHA, "ALPHA8"},
                            {GL_R8, GL_RED, "R8"}};
  Combine operands = irrlicht;
  operands.rgb = GL_INTERPOLATE;
  operands.src_rgb[1] = GL_CONSTANT, operands.op_rgb[1] = GL_ONE_MINUS_SRC_COLOR;
  operands.src_rgb[2] = GL_TEXTURE, operands.op_rgb[2] = GL_ONE_MINUS_SRC_ALPHA;
  operands.alpha = GL_ADD_SIGNED, operands.op_alpha[0] = GL_ONE_MINUS_SRC_ALPHA;
  for (const Format& f : formats) {
    texture(f.internal, f.format, 2);
    set_combine(irrlicht);
    expect_match(std::string("COMBINE MODULATE(TEXTURE, PRIMARY_COLOR), ") + f.name);
    set_combine(operands);
    expect_match(std::string("COMBINE INTERPOLATE, every operand, ") + f.name);
  }
}

// GL_COMBINE on two units with the crossbar: unit 1 reads unit 0's texture
// (GL_TEXTURE0) and the previous stage, unit 0 reads unit 1's (GL_TEXTURE1);
// unit 1 under GL_COMBINE after a legacy mode on unit 0, and PRIMARY_COLOR
// against PREVIOUS on unit 1. Then a program of a state with one combine
// field wrong fails the comparison.
TEST_F(FfProgram, TextureCombineCrossbarMatchesFixedFunction) {
  const float env0[] = {0.2f, 0.7f, 0.4f, 0.6f}, env1[] = {0.9f, 0.3f, 0.6f, 0.4f};
  texture(GL_RGBA8, GL_RGBA);
  glEnable(GL_TEXTURE_2D);
  glTexEnvfv(GL_TEXTURE_ENV, GL_TEXTURE_ENV_COLOR, env0);
  Combine c0;
  c0.src_rgb[1] = c0.src_alpha[1] = GL_PRIMARY_COLOR;
  set_combine(c0);
  ActiveTexture(GL_TEXTURE1);
  texture(GL_RGB8, GL_RGB, 3);
  glEnable(GL_TEXTURE_2D);
  glTexEnvfv(GL_TEXTURE_ENV, GL_TEXTURE_ENV_COLOR, env1);
  glMatrixMode(GL_TEXTURE);
  glLoadIdentity();
  glRotatef(30, 0, 0, 1);
  glMatrixMode(GL_MODELVIEW);
  Combine c1;  // INTERPOLATE(TEXTURE0, PREVIOUS, TEXTURE1's colour), alpha MODULATE(TEXTURE0, PREVIOUS)
  c1.rgb = GL_INTERPOLATE;
  c1.src_rgb[0] = GL_TEXTURE0, c1.src_rgb[1] = GL_PREVIOUS, c1.src_rgb[2] = GL_TEXTURE;
  c1.op_rgb[2] = GL_SRC_COLOR;
  c1.src_alpha[0] = GL_TEXTURE0, c1.src_alpha[1] = GL_PREVIOUS;
  set_combine(c1);
  ActiveTexture(GL_TEXTURE0);
  const FixedFunctionState right = read();
  ASSERT_TRUE(right.units[0].active() && right.units[1].active());
  EXPECT_EQ(right.units[1].combine.rgb_args[0].source, CombineSource::kTextureUnit);
  EXPECT_EQ(right.units[1].combine.rgb_args[0].unit, 0);
  const Image crossbar = expect_match("unit 1 INTERPOLATE(TEXTURE0, PREVIOUS, TEXTURE)");

  ActiveTexture(GL_TEXTURE1);
  Combine c1p = c1;
  c1p.src_rgb[1] = GL_PRIMARY_COLOR;
  set_combine(c1p);
  ActiveTexture(GL_TEXTURE0);
  const Image primary = expect_match("unit 1 INTERPOLATE(TEXTURE0, PRIMARY_COLOR, TEXTURE)");
  expect_differs(crossbar, primary, 0.3, "PRIMARY_COLOR for PREVIOUS on unit 1");

  // Unit 0 reads unit 1's texture (sampled before unit 0's stage).
  Combine c0x = c0;
  c0x.rgb = GL_ADD_SIGNED;
  c0x.src_rgb[1] = GL_TEXTURE1;
  c0x.alpha = GL_SUBTRACT;
  c0x.src_alpha[0] = GL_TEXTURE1;
  c0x.op_alpha[0] = GL_ONE_MINUS_SRC_ALPHA;
  set_combine(c0x);
  expect_match("unit 0 ADD_SIGNED(TEXTURE, TEXTURE1)");
  glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_DECAL);
  expect_match("unit 0 GL_DECAL, unit 1 combine");

  // A wrong combine field fails the comparison.
  ActiveTexture(GL_TEXTURE1);
  set_combine(c1);
  ActiveTexture(GL_TEXTURE0);
  set_combine(c0);
  ASSERT_EQ(read(), right);
  const Image ff = render(nullptr);
  ASSERT_GE(compare(ff, render(&right), 1).within, 0.999);
  auto expect_caught = [&](const char* what, const FixedFunctionState& wrong) {
    EXPECT_NE(wrong, right) << what << ": the states must compare unequal";
    const Image img = render(&wrong);
    ASSERT_FALSE(img.rgba.empty()) << what;
    EXPECT_LT(compare(ff, img, 1).within, 0.99) << what << ": the comparison must fail";
  };
  FixedFunctionState w = right;
  w.units[1].combine.rgb_args[2].operand = CombineOperand::kOneMinusSrcColor;
  expect_caught("ONE_MINUS_SRC_COLOR for SRC_COLOR", w);
  w = right;
  w.units[1].combine.rgb_args[0] = CombineArg{};
  expect_caught("TEXTURE for TEXTURE0", w);
  w = right;
  w.units[1].combine.rgb_args[1].source = CombineSource::kPrimaryColor;
  expect_caught("PRIMARY_COLOR for PREVIOUS", w);
  w = right;
  w.units[0].combine.rgb_scale = 2;
  expect_caught("RGB_SCALE 2 for 1", w);
  w = right;
  w.units[0].combine.alpha = CombineFunc::kAdd;
  expect_caught("ADD for MODULATE alpha", w);
  w = right;
  w.units[1].combine.rgb = CombineFunc::kAddSigned;
  expect_caught("ADD_SIGNED for INTERPOLATE", w);
}

// GL_LIGHTING: a directional light and an attenuated point light, a
// material with ambient, diffuse, specular, emission and shininess, the
// scene ambient colour; then GL_COLOR_MATERIAL, the local viewer, a
// spotlight, the separate specular colour and GL_RESCALE_NORMAL. Both light
// per vertex, so the bound of 1/255 holds here too.
TEST_F(FfProgram, LightingMatchesFixedFunction) {
  const Image unlit = expect_match("unlit");
  lights_and_material();
  FixedFunctionState s = read();
  EXPECT_TRUE(s.lighting);
  EXPECT_TRUE(s.lights[0].enabled && s.lights[0].directional && !s.lights[0].spot);
  EXPECT_TRUE(s.lights[1].enabled && !s.lights[1].directional && s.lights[1].attenuated);
  EXPECT_FALSE(s.lights[2].enabled);
  const Image lit = expect_match("two lights, material");
  expect_differs(unlit, lit, 0.8, "GL_LIGHTING");
  glDisable(GL_LIGHT1);
  const Image one_light = expect_match("light 0 only");
  expect_differs(lit, one_light, 0.3, "GL_LIGHT1");
  glEnable(GL_LIGHT1);

  glColorMaterial(GL_FRONT_AND_BACK, GL_AMBIENT_AND_DIFFUSE);
  glEnable(GL_COLOR_MATERIAL);
  EXPECT_TRUE(read().color_material);
  const Image tracked = expect_match("GL_COLOR_MATERIAL, ambient and diffuse");
  expect_differs(lit, tracked, 0.5, "GL_COLOR_MATERIAL");
  glColorMaterial(GL_FRONT, GL_SPECULAR);
  expect_match("GL_COLOR_MATERIAL, specular");
  glColorMaterial(GL_FRONT, GL_EMISSION);
  expect_match("GL_COLOR_MATERIAL, emission");
  glDisable(GL_COLOR_MATERIAL);
  material();

  glLightModeli(GL_LIGHT_MODEL_LOCAL_VIEWER, GL_TRUE);
  expect_match("local viewer");
  glLightModeli(GL_LIGHT_MODEL_COLOR_CONTROL, GL_SEPARATE_SPECULAR_COLOR);
  texture(GL_RGB8, GL_RGB);
  glEnable(GL_TEXTURE_2D);
  expect_match("separate specular colour, textured");
  glDisable(GL_TEXTURE_2D);
  glLightModeli(GL_LIGHT_MODEL_COLOR_CONTROL, GL_SINGLE_COLOR);
  glLightModeli(GL_LIGHT_MODEL_LOCAL_VIEWER, GL_FALSE);

  glPushMatrix();
  glLoadIdentity();
  const float spot_dir[] = {-0.3f, -0.3f, -1};
  glLightfv(GL_LIGHT1, GL_SPOT_DIRECTION, spot_dir);
  glPopMatrix();
  glLightf(GL_LIGHT1, GL_SPOT_CUTOFF, 40);
  glLightf(GL_LIGHT1, GL_SPOT_EXPONENT, 6);
  EXPECT_TRUE(read().lights[1].spot);
  const Image spot = expect_match("spotlight");
  expect_differs(lit, spot, 0.1, "the spotlight");

  glDisable(GL_NORMALIZE);
  glEnable(GL_RESCALE_NORMAL);
  glScalef(1.2f, 1.2f, 1.2f);
  s = read();
  EXPECT_TRUE(s.rescale_normal && !s.normalize);
  expect_match("GL_RESCALE_NORMAL");
}

// GL_ALPHA_TEST with every function against 0.5 (the grid's alpha runs from
// 0.2 to 1): the program's discard drops the same fragments.
TEST_F(FfProgram, AlphaTestMatchesFixedFunction) {
  const Image all = expect_match("no alpha test");
  glEnable(GL_ALPHA_TEST);
  const std::pair<GLenum, const char*> funcs[] = {
      {GL_NEVER, "NEVER"},     {GL_LESS, "LESS"},         {GL_EQUAL, "EQUAL"},   {GL_LEQUAL, "LEQUAL"},
      {GL_GREATER, "GREATER"}, {GL_NOTEQUAL, "NOTEQUAL"}, {GL_GEQUAL, "GEQUAL"}, {GL_ALWAYS, "ALWAYS"}};
  for (float ref : {0.5f, 0.3f, 0.77f})
    for (auto [func, name] : funcs) {
      glAlphaFunc(func, ref);
      const FixedFunctionState s = read();
      EXPECT_EQ(s.alpha_test, func != GL_ALWAYS) << name;
      SCOPED_TRACE(std::string(name) + " " + std::to_string(ref));
      const Image ff = render(nullptr);
      const Image prog = render(&s);
      ASSERT_FALSE(prog.rgba.empty());
      const Comparison c = compare(ff, prog, 1);
      EXPECT_GE(c.within, 0.999) << "max diff " << c.max_diff;
      if (ref == 0.5f && (func == GL_GREATER || func == GL_LESS)) {
        // About half the grid is discarded, and the image shows it.
        EXPECT_GT(covered(ff, clear_), 0.1);
        expect_differs(all, ff, 0.15, "the alpha test");
      }
      if (func == GL_NEVER) {
        EXPECT_EQ(covered(prog, clear_), 0.0) << "GL_NEVER discards every fragment";
      }
    }
}

// GL_FOG: linear, exp and exp2 from the eye depth, and linear from the fog
// coordinate array.
TEST_F(FfProgram, FogMatchesFixedFunction) {
  const Image clear = expect_match("no fog");
  const float fog_color[] = {0.8f, 0.75f, 0.7f, 1};
  glFogfv(GL_FOG_COLOR, fog_color);
  glFogf(GL_FOG_START, 3.0f);
  glFogf(GL_FOG_END, 6.0f);
  glFogf(GL_FOG_DENSITY, 0.3f);
  glEnable(GL_FOG);
  const std::pair<GLenum, const char*> modes[] = {{GL_LINEAR, "LINEAR"}, {GL_EXP, "EXP"}, {GL_EXP2, "EXP2"}};
  for (auto [mode, name] : modes) {
    glFogi(GL_FOG_MODE, GLint(mode));
    const Image fogged = expect_match(std::string("GL_") + name + ", eye depth");
    expect_differs(clear, fogged, 0.5, std::string("GL_") + name + " fog");
  }
  glFogi(GL_FOG_MODE, GL_LINEAR);
  glFogi(GL_FOG_COORD_SRC, GL_FOG_COORD);
  EXPECT_EQ(read().fog_source, FogSource::kFogCoord);
  expect_match("GL_LINEAR, fog coordinate");
}

// The comparison catches a wrong program: the program of a state that
// differs in one feature from the context's does not pass the bound.
TEST_F(FfProgram, TheComparisonDetectsAWrongProgram) {
  texture(GL_RGBA8, GL_RGBA);
  glEnable(GL_TEXTURE_2D);
  glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_MODULATE);
  glAlphaFunc(GL_GREATER, 0.3f);
  glEnable(GL_ALPHA_TEST);
  glFogi(GL_FOG_MODE, GL_LINEAR);
  glFogf(GL_FOG_START, 3.0f);
  glFogf(GL_FOG_END, 6.0f);
  glEnable(GL_FOG);
  const FixedFunctionState right = read();
  const Image ff = render(nullptr);
  const Image good = render(&right);
  EXPECT_GE(compare(ff, good, 1).within, 0.999) << "the right program matches";
  auto expect_caught = [&](const char* what, FixedFunctionState wrong) {
    const Image img = render(&wrong);
    ASSERT_FALSE(img.rgba.empty()) << what;
    EXPECT_LT(compare(ff, img, 1).within, 0.99) << what << ": the comparison must fail";
  };
  FixedFunctionState w = right;
  w.units[0].env = TexEnvMode::kAdd;
  expect_caught("GL_ADD for GL_MODULATE", w);
  w = right;
  w.units[0].env = TexEnvMode::kReplace;
  expect_caught("GL_REPLACE for GL_MODULATE", w);
  w = right;
  w.alpha_func = CompareFunc::kLess;
  expect_caught("GL_LESS for GL_GREATER", w);
  w = right;
  w.fog_mode = FogMode::kExp;
  expect_caught("GL_EXP for GL_LINEAR fog", w);
  w = right;
  w.flat_shading = true;
  expect_caught("flat for smooth shading", w);
}

// Programs of states across the subset compile and link: 256 states from a
// fixed-seed generator over every field the generator reads.
TEST_F(FfProgram, ProgramsOfManyStatesCompile) {
  uint32_t x = 12345;
  auto next = [&](uint32_t n) {
    x = x * 1664525u + 1013904223u;
    return (x >> 8) % n;
  };
  for (int k = 0; k < 256; ++k) {
    FixedFunctionState s;
    s.flat_shading = next(2);
    s.lighting = next(2);
    s.color_sum = !s.lighting && next(2);
    if (s.lighting) {
      for (auto& l : s.lights) {
        l.enabled = next(3) == 0;
        if (!l.enabled) continue;
        l.directional = next(2);
        l.attenuated = !l.directional && next(2);
        l.spot = next(2);
      }
      s.local_viewer = next(2);
      s.separate_specular = next(2);
      s.color_material = next(2);
      s.color_material_parameter = ColorMaterialParameter(next(5));
      s.normalize = next(2);
      s.rescale_normal = !s.normalize && next(2);
    }
    for (auto& t : s.units) {
      if (next(2)) continue;
      t.target = TexTarget::k2D;
      t.complete = true;
      t.base = TexBaseFormat(next(6));
      t.env = TexEnvMode(next(5));
      if (t.env == TexEnvMode::kDecal) t.base = next(2) ? TexBaseFormat::kRgb : TexBaseFormat::kRgba;
    }
    s.alpha_test = next(2);
    if (s.alpha_test) {
      s.alpha_func = CompareFunc(next(7));
      s.alpha_ref = float(next(1000)) / 999;
      s.alpha_test_bits = next(2) ? 8 : 0;
    }
    s.fog = next(2);
    s.fog_mode = FogMode(next(3));
    s.fog_source = FogSource(next(2));
    s.clip_planes = uint8_t(next(4));
    ASSERT_EQ(unsupported_reason(s), "") << "state " << k;
    const GLuint prog = link(fixed_function_program(s));
    ASSERT_NE(prog, 0u) << "state " << k;
    DeleteProgram(prog);
  }
  // GL_COMBINE on one or both units: every function, source (the crossbar to
  // the other unit when it is on), operand and scale.
  for (int k = 0; k < 128; ++k) {
    FixedFunctionState s;
    s.flat_shading = next(2);
    const int units = 1 + int(next(3));  // bit u: unit u on
    for (int u = 0; u < FixedFunctionState::kUnits; ++u) {
      if (!(units & (1 << u))) continue;
      TextureUnitState& t = s.units[size_t(u)];
      t.target = TexTarget::k2D;
      t.complete = true;
      t.base = TexBaseFormat(next(6));
      t.env = next(4) ? TexEnvMode::kCombine : TexEnvMode::kModulate;
      if (t.env != TexEnvMode::kCombine) continue;
      auto arg = [&](bool alpha) {
        CombineArg a;
        a.source = CombineSource(next(5));
        if (a.source == CombineSource::kTextureUnit) {
          if (units == 3)
            a.unit = uint8_t(1 - u);
          else
            a.source = CombineSource::kTexture;
        }
        a.operand =
            alpha ? (next(2) ? CombineOperand::kSrcAlpha : CombineOperand::kOneMinusSrcAlpha) : CombineOperand(next(4));
        return a;
      };
      CombineState& c = t.combine;
      c.rgb = CombineFunc(next(8));
      c.alpha = CombineFunc(next(6));
      for (auto& a : c.rgb_args) a = arg(false);
      for (auto& a : c.alpha_args) a = arg(true);
      c.rgb_scale = uint8_t(1 << next(3));
      c.alpha_scale = uint8_t(1 << next(3));
    }
    ASSERT_EQ(unsupported_reason(s), "") << "combine state " << k;
    const GLuint prog = link(fixed_function_program(s));
    ASSERT_NE(prog, 0u) << "combine state " << k;
    DeleteProgram(prog);
  }
}

// Features outside the subset are named, read from a real context.
TEST_F(FfProgram, UnsupportedFeaturesAreNamed) {
  texture(GL_RGBA8, GL_RGBA);
  glEnable(GL_TEXTURE_2D);
  EXPECT_EQ(unsupported_reason(read()), "");

  glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_COMBINE);
  EXPECT_EQ(unsupported_reason(read()), "");
  glTexEnvi(GL_TEXTURE_ENV, GL_SRC1_RGB, GL_TEXTURE1);
  EXPECT_EQ(unsupported_reason(read()),
            "GL_COMBINE: GL_SRC1_RGB = GL_TEXTURE1, a unit without an enabled complete texture (undefined in GL) on "
            "texture unit 0");
  glTexEnvi(GL_TEXTURE_ENV, GL_SRC1_RGB, GL_PREVIOUS);
  glTexEnvi(GL_TEXTURE_ENV, GL_COMBINE_RGB, GL_REPLACE);
  glTexEnvi(GL_TEXTURE_ENV, GL_SRC1_RGB, GL_TEXTURE1);
  EXPECT_EQ(unsupported_reason(read()), "") << "REPLACE does not read Arg1";
  glTexEnvi(GL_TEXTURE_ENV, GL_SRC1_RGB, GL_PREVIOUS);
  glTexEnvi(GL_TEXTURE_ENV, GL_COMBINE_RGB, GL_MODULATE);
  glGetError();
  glTexEnvi(GL_TEXTURE_ENV, GL_COMBINE_RGB, GL_MODULATE_ADD_ATI);
  // ATI_texture_env_combine3 (Mesa has it): a function and a source outside the subset.
  ASSERT_EQ(glGetError(), GLenum(GL_NO_ERROR)) << "GL_MODULATE_ADD_ATI";
  EXPECT_EQ(unsupported_reason(read()),
            "GL_COMBINE: a GL_COMBINE_RGB function other than REPLACE, MODULATE, ADD, ADD_SIGNED, INTERPOLATE, "
            "SUBTRACT, DOT3_RGB, DOT3_RGBA on texture unit 0");
  glTexEnvi(GL_TEXTURE_ENV, GL_COMBINE_RGB, GL_MODULATE);
  glTexEnvi(GL_TEXTURE_ENV, GL_SRC0_ALPHA, GL_ZERO);
  ASSERT_EQ(glGetError(), GLenum(GL_NO_ERROR)) << "GL_ZERO as a combiner source";
  EXPECT_EQ(unsupported_reason(read()),
            "GL_COMBINE: a GL_SRC0_ALPHA other than TEXTURE, TEXTUREi, CONSTANT, PRIMARY_COLOR, PREVIOUS on texture "
            "unit 0");
  glTexEnvi(GL_TEXTURE_ENV, GL_SRC0_ALPHA, GL_TEXTURE);
  glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_MODULATE);
  EXPECT_EQ(read().units[0].combine, CombineState{}) << "the combine state is read under GL_COMBINE only";

  glEnable(GL_TEXTURE_GEN_S);
  EXPECT_EQ(unsupported_reason(read()), "glTexGen on texture unit 0");
  glDisable(GL_TEXTURE_GEN_S);

  glTexEnvf(GL_TEXTURE_FILTER_CONTROL, GL_TEXTURE_LOD_BIAS, 0.5f);
  EXPECT_EQ(unsupported_reason(read()), "a texture environment LOD bias (GL_TEXTURE_LOD_BIAS) on texture unit 0");
  glTexEnvf(GL_TEXTURE_FILTER_CONTROL, GL_TEXTURE_LOD_BIAS, 0);

  ActiveTexture(GL_TEXTURE2);
  texture(GL_RGBA8, GL_RGBA);
  glEnable(GL_TEXTURE_2D);
  EXPECT_EQ(unsupported_reason(read()), "texture unit 2 enabled");
  glDisable(GL_TEXTURE_2D);
  ActiveTexture(GL_TEXTURE0);

  // A unit whose texture has no image is off in fixed function: supported.
  ActiveTexture(GL_TEXTURE3);
  glBindTexture(GL_TEXTURE_2D, 0);
  glEnable(GL_TEXTURE_2D);
  EXPECT_EQ(unsupported_reason(read()), "");
  glDisable(GL_TEXTURE_2D);
  ActiveTexture(GL_TEXTURE0);

  GLuint cube = 0;
  glGenTextures(1, &cube);
  textures_.push_back(cube);
  glBindTexture(GL_TEXTURE_CUBE_MAP, cube);
  const unsigned char texel[4] = {255, 0, 0, 255};
  for (int f = 0; f < 6; ++f)
    glTexImage2D(GL_TEXTURE_CUBE_MAP_POSITIVE_X + GLenum(f), 0, GL_RGBA8, 1, 1, 0, GL_RGBA, GL_UNSIGNED_BYTE, texel);
  glTexParameteri(GL_TEXTURE_CUBE_MAP, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glEnable(GL_TEXTURE_CUBE_MAP);
  EXPECT_EQ(unsupported_reason(read()), "GL_TEXTURE_CUBE_MAP on texture unit 0");
  glDisable(GL_TEXTURE_CUBE_MAP);

  texture(GL_LUMINANCE8, GL_LUMINANCE);
  glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_DECAL);
  EXPECT_EQ(unsupported_reason(read()), "GL_DECAL with a GL_LUMINANCE texture (undefined in GL) on texture unit 0");
  glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_MODULATE);

  glEnable(GL_LIGHTING);
  EXPECT_EQ(unsupported_reason(read()), "");
  glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, GL_TRUE);
  EXPECT_EQ(unsupported_reason(read()), "two-sided lighting (GL_LIGHT_MODEL_TWO_SIDE)");
  glDisable(GL_LIGHTING);
  EXPECT_EQ(unsupported_reason(read()), "") << "two-sided lighting matters only with lighting";

  glEnable(GL_VERTEX_PROGRAM_ARB);
  EXPECT_EQ(unsupported_reason(read()), "an ARB vertex program (GL_VERTEX_PROGRAM_ARB enabled)");
  glDisable(GL_VERTEX_PROGRAM_ARB);

  const float atten[] = {1, 0.5f, 0};
  auto PointParameterfv = reinterpret_cast<PFNGLPOINTPARAMETERFVPROC>(OSMesaGetProcAddress("glPointParameterfv"));
  ASSERT_NE(PointParameterfv, nullptr);
  PointParameterfv(GL_POINT_DISTANCE_ATTENUATION, atten);
  EXPECT_EQ(unsupported_reason(read()), "point size distance attenuation (GL_POINT_DISTANCE_ATTENUATION)");
  const float none[] = {1, 0, 0};
  PointParameterfv(GL_POINT_DISTANCE_ATTENUATION, none);

  glEnable(GL_POINT_SPRITE);
  EXPECT_EQ(unsupported_reason(read()), "") << "point sprites without coordinate replacement change nothing";
  glTexEnvi(GL_POINT_SPRITE, GL_COORD_REPLACE, GL_TRUE);
  EXPECT_EQ(unsupported_reason(read()), "point sprite texture coordinates (GL_COORD_REPLACE)");
}

// Same state, same bytes; the source holds only the enabled features; states
// that render differently give different sources.
TEST(FfProgramSource, IsDeterministicAndMinimal) {
  FixedFunctionState plain;
  const GlslProgram a = fixed_function_program(plain), b = fixed_function_program(FixedFunctionState{});
  EXPECT_EQ(a.vertex, b.vertex);
  EXPECT_EQ(a.fragment, b.fragment);
  for (const char* feature : {"gl_LightSource", "textureProj", "gl_Fog", "discard", "flat", "ff_secondary",
                              "gl_ClipVertex", "sampler2D", "gl_ModelViewMatrix"}) {
    EXPECT_EQ(a.vertex.find(feature), std::string::npos) << feature << " in the vertex shader of the plain state";
    EXPECT_EQ(a.fragment.find(feature), std::string::npos) << feature << " in the fragment shader of the plain state";
  }
  EXPECT_NE(a.fragment.find("gl_FragColor = color;"), std::string::npos);

  FixedFunctionState lit;
  lit.lighting = true;
  lit.lights[0].enabled = lit.lights[0].directional = true;
  lit.lights[3].enabled = lit.lights[3].attenuated = true;
  const GlslProgram l1 = fixed_function_program(lit), l2 = fixed_function_program(lit);
  EXPECT_EQ(l1.vertex, l2.vertex);
  EXPECT_EQ(l1.fragment, l2.fragment);
  EXPECT_NE(l1.vertex.find("gl_LightSource[0]"), std::string::npos);
  EXPECT_NE(l1.vertex.find("gl_LightSource[3].quadraticAttenuation"), std::string::npos);
  EXPECT_EQ(l1.vertex.find("gl_LightSource[1]"), std::string::npos) << "a disabled light has no code";
  EXPECT_EQ(l1.vertex.find("spotCosCutoff"), std::string::npos) << "no spotlight, no spot code";

  FixedFunctionState tex;
  tex.units[1].target = TexTarget::k2D;
  tex.units[1].complete = true;
  tex.alpha_test = true;
  tex.alpha_func = CompareFunc::kGequal;
  tex.alpha_ref = 0.1f;
  const GlslProgram t = fixed_function_program(tex);
  EXPECT_NE(t.fragment.find("layout(binding = 1) uniform sampler2D ff_texture1;"), std::string::npos);
  EXPECT_EQ(t.fragment.find("ff_texture0"), std::string::npos) << "unit 0 is off";
  EXPECT_NE(t.fragment.find("if (!(color.a >= 0.1)) discard;"), std::string::npos)
      << "the reference reads back as the same float: " << t.fragment;

  // Every field that shapes the program changes the source.
  std::vector<FixedFunctionState> states(8, plain);
  states[0].flat_shading = true;
  states[1].color_sum = true;
  states[2] = lit;
  states[3] = lit, states[3].local_viewer = true;
  states[4] = lit, states[4].lights[3].spot = true;
  states[5] = tex;
  states[6] = tex, states[6].units[1].env = TexEnvMode::kAdd;
  states[7].fog = true, states[7].fog_mode = FogMode::kExp2;
  for (size_t i = 0; i < states.size(); ++i) {
    const GlslProgram p = fixed_function_program(states[i]);
    EXPECT_NE(p.vertex + p.fragment, a.vertex + a.fragment) << "state " << i;
    for (size_t j = 0; j < i; ++j) {
      const GlslProgram q = fixed_function_program(states[j]);
      EXPECT_NE(p.vertex + p.fragment, q.vertex + q.fragment) << "states " << j << " and " << i;
    }
  }
}

// The GL_COMBINE program: the function, its arguments (source and operand),
// the scales and the crossbar in the source text; every combine field is part
// of the state's equality (the cache key) and changes the source.
TEST(FfProgramSource, CombineSourceAndCacheKey) {
  FixedFunctionState s;
  TextureUnitState& t = s.units[0];
  t.target = TexTarget::k2D;
  t.complete = true;
  t.env = TexEnvMode::kCombine;
  t.combine.rgb_args[1].source = t.combine.alpha_args[1].source = CombineSource::kPrimaryColor;
  t.combine.rgb_scale = 2;
  ASSERT_EQ(unsupported_reason(s), "");
  std::string f = fixed_function_program(s).fragment;
  EXPECT_NE(f.find("vec4 t0 = textureProj(ff_texture0, ff_texcoord0);"), std::string::npos) << f;
  EXPECT_NE(f.find("vec3 rgb0 = t0.rgb * ff_color.rgb;"), std::string::npos) << f;
  EXPECT_NE(f.find("float alpha0 = t0.a * ff_color.a;"), std::string::npos) << f;
  EXPECT_NE(f.find("color = vec4(clamp(rgb0 * 2.0, 0.0, 1.0), clamp(alpha0, 0.0, 1.0));"), std::string::npos) << f;

  // INTERPOLATE(CONSTANT, PREVIOUS, ONE_MINUS_SRC_ALPHA of TEXTURE), ALPHA ADD_SIGNED x 4.
  t.combine.rgb = CombineFunc::kInterpolate;
  t.combine.rgb_args = {CombineArg{CombineSource::kConstant, 0, CombineOperand::kSrcColor},
                        CombineArg{CombineSource::kPrevious, 0, CombineOperand::kOneMinusSrcColor},
                        CombineArg{CombineSource::kTexture, 0, CombineOperand::kOneMinusSrcAlpha}};
  t.combine.alpha = CombineFunc::kAddSigned;
  t.combine.alpha_scale = 4;
  f = fixed_function_program(s).fragment;
  EXPECT_NE(f.find("vec3 rgb0 = gl_TextureEnvColor[0].rgb * vec3(1.0 - t0.a) + (1.0 - color.rgb) * (1.0 - vec3(1.0 - "
                   "t0.a));"),
            std::string::npos)
      << f;
  EXPECT_NE(f.find("float alpha0 = t0.a + ff_color.a - 0.5;"), std::string::npos) << f;
  EXPECT_NE(f.find("clamp(alpha0 * 4.0, 0.0, 1.0)"), std::string::npos) << f;

  // DOT3_RGBA: the dot product in all four components, ALPHA's function ignored.
  t.combine = CombineState{};
  t.combine.rgb = CombineFunc::kDot3Rgba;
  t.combine.rgb_args[1] = CombineArg{CombineSource::kPrimaryColor, 0, CombineOperand::kSrcAlpha};
  f = fixed_function_program(s).fragment;
  EXPECT_NE(f.find("float dot0 = 4.0 * dot(t0.rgb - 0.5, vec3(ff_color.a) - 0.5);"), std::string::npos) << f;
  EXPECT_NE(f.find("float alpha0 = dot0;"), std::string::npos) << f;
  t.combine.rgb = CombineFunc::kDot3Rgb;
  f = fixed_function_program(s).fragment;
  EXPECT_NE(f.find("vec3 rgb0 = vec3(dot0);"), std::string::npos) << f;
  EXPECT_NE(f.find("float alpha0 = t0.a * color.a;"), std::string::npos) << f;

  // The crossbar: unit 1 reads unit 0's texel, sampled before either stage.
  FixedFunctionState two = s;
  two.units[0].env = TexEnvMode::kModulate;
  two.units[0].combine = CombineState{};
  two.units[1] = t;
  two.units[1].combine = CombineState{};
  two.units[1].combine.rgb = CombineFunc::kSubtract;
  two.units[1].combine.rgb_args[1] = CombineArg{CombineSource::kTextureUnit, 0, CombineOperand::kSrcColor};
  ASSERT_EQ(unsupported_reason(two), "");
  f = fixed_function_program(two).fragment;
  EXPECT_NE(f.find("vec3 rgb1 = t1.rgb - t0.rgb;"), std::string::npos) << f;
  EXPECT_LT(f.find("vec4 t1 = textureProj"), f.find("// unit 0")) << f;

  // Every field is in the cache key and in the source.
  FixedFunctionState base;
  base.units[0] = t;
  base.units[0].combine = CombineState{};
  base.units[1] = base.units[0];
  std::vector<FixedFunctionState> states(12, base);
  states[1].units[0].env = TexEnvMode::kModulate;
  states[2].units[0].combine.rgb = CombineFunc::kAdd;
  states[3].units[0].combine.alpha = CombineFunc::kSubtract;
  states[4].units[0].combine.rgb_args[0].operand = CombineOperand::kOneMinusSrcColor;
  states[5].units[0].combine.rgb_args[1].source = CombineSource::kConstant;
  states[6].units[0].combine.rgb_args[1] = CombineArg{CombineSource::kTextureUnit, 1, CombineOperand::kSrcColor};
  states[7].units[1].combine.rgb_args[0] = CombineArg{CombineSource::kTextureUnit, 0, CombineOperand::kSrcColor};
  states[8].units[0].combine.alpha_args[0].operand = CombineOperand::kOneMinusSrcAlpha;
  states[9].units[0].combine.alpha_args[1].source = CombineSource::kPrimaryColor;
  states[10].units[0].combine.rgb_scale = 4;
  states[11].units[1].combine.alpha_scale = 2;
  for (size_t i = 0; i < states.size(); ++i) {
    ASSERT_EQ(unsupported_reason(states[i]), "") << "state " << i;
    const GlslProgram p = fixed_function_program(states[i]);
    for (size_t j = 0; j < i; ++j) {
      EXPECT_NE(states[i], states[j]) << "states " << j << " and " << i;
      const GlslProgram q = fixed_function_program(states[j]);
      EXPECT_NE(p.vertex + p.fragment, q.vertex + q.fragment) << "states " << j << " and " << i;
    }
  }
  FixedFunctionState copy = states[6];
  EXPECT_EQ(copy, states[6]);
  copy.units[0].combine.rgb_args[1].unit = 0;
  EXPECT_NE(copy, states[6]) << "the crossbar's unit is in the key";
}

// unsupported_reason names each feature outside the subset (states built
// directly, including those no context here can make).
TEST(FfProgramSource, UnsupportedReasonNamesEachFeature) {
  EXPECT_EQ(unsupported_reason(FixedFunctionState{}), "");
  auto with = [](const std::function<void(FixedFunctionState&)>& f) {
    FixedFunctionState s;
    s.units[0].target = TexTarget::k2D;
    s.units[0].complete = true;
    f(s);
    return unsupported_reason(s);
  };
  EXPECT_EQ(with([](FixedFunctionState&) {}), "");
  EXPECT_EQ(with([](FixedFunctionState& s) { s.other_unit = 5; }), "texture unit 5 enabled");
  EXPECT_EQ(with([](FixedFunctionState& s) { s.units[0].env = TexEnvMode::kCombine; }), "");
  auto combine = [&](const std::function<void(CombineState&)>& f) {
    return with([&](FixedFunctionState& s) {
      s.units[0].env = TexEnvMode::kCombine;
      f(s.units[0].combine);
    });
  };
  EXPECT_EQ(combine([](CombineState& c) { c.rgb = CombineFunc::kOther; }),
            "GL_COMBINE: a GL_COMBINE_RGB function other than REPLACE, MODULATE, ADD, ADD_SIGNED, INTERPOLATE, "
            "SUBTRACT, DOT3_RGB, DOT3_RGBA on texture unit 0");
  EXPECT_EQ(combine([](CombineState& c) { c.alpha = CombineFunc::kDot3Rgb; }),
            "GL_COMBINE: a GL_COMBINE_ALPHA function other than REPLACE, MODULATE, ADD, ADD_SIGNED, INTERPOLATE, "
            "SUBTRACT on texture unit 0");
  EXPECT_EQ(combine([](CombineState& c) { c.rgb = CombineFunc::kDot3Rgba, c.alpha = CombineFunc::kOther; }), "")
      << "DOT3_RGBA ignores COMBINE_ALPHA";
  EXPECT_EQ(combine([](CombineState& c) { c.rgb_args[1].source = CombineSource::kOther; }),
            "GL_COMBINE: a GL_SRC1_RGB other than TEXTURE, TEXTUREi, CONSTANT, PRIMARY_COLOR, PREVIOUS on texture "
            "unit 0");
  EXPECT_EQ(combine([](CombineState& c) { c.rgb_args[2].source = CombineSource::kOther; }), "")
      << "MODULATE does not read Arg2";
  EXPECT_EQ(combine([](CombineState& c) { c.alpha_args[0].operand = CombineOperand::kSrcColor; }),
            "GL_COMBINE: a GL_OPERAND0_ALPHA GL does not define on texture unit 0");
  EXPECT_EQ(combine([](CombineState& c) {
              c.rgb_args[0] = CombineArg{CombineSource::kTextureUnit, 1};
            }),
            "GL_COMBINE: GL_SRC0_RGB = GL_TEXTURE1, a unit without an enabled complete texture (undefined in GL) on "
            "texture unit 0");
  EXPECT_EQ(combine([](CombineState& c) {
              c.alpha_args[1] = CombineArg{CombineSource::kTextureUnit, 4, CombineOperand::kSrcAlpha};
            }),
            "GL_COMBINE: GL_SRC1_ALPHA = GL_TEXTURE4, a unit without an enabled complete texture (undefined in GL) "
            "on texture unit 0");
  EXPECT_EQ(combine([](CombineState& c) { c.rgb_scale = 0; }),
            "GL_COMBINE: a GL_RGB_SCALE other than 1, 2, 4 on texture unit 0");
  EXPECT_EQ(combine([](CombineState& c) { c.alpha_scale = 0; }),
            "GL_COMBINE: a GL_ALPHA_SCALE other than 1, 2, 4 on texture unit 0");
  EXPECT_EQ(with([](FixedFunctionState& s) {
              s.units[1] = s.units[0];
              s.units[0].env = TexEnvMode::kCombine;
              s.units[0].combine.rgb_args[0] = CombineArg{CombineSource::kTextureUnit, 1};
            }),
            "")
      << "the crossbar to an enabled unit";
  EXPECT_EQ(with([](FixedFunctionState& s) { s.units[0].target = TexTarget::k3D; }), "GL_TEXTURE_3D on texture unit 0");
  EXPECT_EQ(with([](FixedFunctionState& s) { s.units[0].target = TexTarget::k1D; }), "GL_TEXTURE_1D on texture unit 0");
  EXPECT_EQ(with([](FixedFunctionState& s) { s.units[0].target = TexTarget::kRectangle; }),
            "GL_TEXTURE_RECTANGLE on texture unit 0");
  EXPECT_EQ(with([](FixedFunctionState& s) { s.units[0].base = TexBaseFormat::kDepth; }),
            "a depth texture on texture unit 0");
  EXPECT_EQ(with([](FixedFunctionState& s) { s.units[0].complete = false, s.units[0].env = TexEnvMode::kCombine; }), "")
      << "an incomplete unit is off";
  EXPECT_EQ(with([](FixedFunctionState& s) { s.units[1] = s.units[0], s.units[1].texgen = true; }),
            "glTexGen on texture unit 1");
  EXPECT_EQ(with([](FixedFunctionState& s) { s.units[0].env = TexEnvMode::kOther; }),
            "a texture environment mode other than MODULATE, REPLACE, DECAL, ADD, BLEND, COMBINE on texture unit 0");
  EXPECT_EQ(with([](FixedFunctionState& s) { s.lighting = s.two_sided = true; }),
            "two-sided lighting (GL_LIGHT_MODEL_TWO_SIDE)");
  EXPECT_EQ(with([](FixedFunctionState& s) { s.arb_fragment_program = true; }),
            "an ARB fragment program (GL_FRAGMENT_PROGRAM_ARB enabled)");
}

}  // namespace
