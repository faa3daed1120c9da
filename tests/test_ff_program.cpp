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

#include "ff_program.h"

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
}

// Features outside the subset are named, read from a real context.
TEST_F(FfProgram, UnsupportedFeaturesAreNamed) {
  texture(GL_RGBA8, GL_RGBA);
  glEnable(GL_TEXTURE_2D);
  EXPECT_EQ(unsupported_reason(read()), "");

  glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_COMBINE);
  EXPECT_EQ(unsupported_reason(read()), "GL_COMBINE texture environment on texture unit 0");
  glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_MODULATE);

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
  EXPECT_EQ(with([](FixedFunctionState& s) { s.units[0].env = TexEnvMode::kCombine; }),
            "GL_COMBINE texture environment on texture unit 0");
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
