#include "traces/capture/mesa_capture.h"

// osmesa.h (GL/gl.h) defines the types glext.h uses: keep this order.
// clang-format off
#include <GL/osmesa.h>
#include <GL/glext.h>
// clang-format on
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>

namespace ropsim {

namespace {

/// The GL 2.0+ entry points, from OSMesaGetProcAddress (GL 1.1 ones are linked).
struct GlFunctions {
#define ROPSIM_GL(type, name) type name = nullptr;
#define ROPSIM_GL_LIST                                                               \
  ROPSIM_GL(PFNGLGENFRAMEBUFFERSPROC, GenFramebuffers)                               \
  ROPSIM_GL(PFNGLBINDFRAMEBUFFERPROC, BindFramebuffer)                               \
  ROPSIM_GL(PFNGLDELETEFRAMEBUFFERSPROC, DeleteFramebuffers)                         \
  ROPSIM_GL(PFNGLGENRENDERBUFFERSPROC, GenRenderbuffers)                             \
  ROPSIM_GL(PFNGLBINDRENDERBUFFERPROC, BindRenderbuffer)                             \
  ROPSIM_GL(PFNGLDELETERENDERBUFFERSPROC, DeleteRenderbuffers)                       \
  ROPSIM_GL(PFNGLRENDERBUFFERSTORAGEMULTISAMPLEPROC, RenderbufferStorageMultisample) \
  ROPSIM_GL(PFNGLFRAMEBUFFERRENDERBUFFERPROC, FramebufferRenderbuffer)               \
  ROPSIM_GL(PFNGLCHECKFRAMEBUFFERSTATUSPROC, CheckFramebufferStatus)                 \
  ROPSIM_GL(PFNGLCREATESHADERPROC, CreateShader)                                     \
  ROPSIM_GL(PFNGLSHADERSOURCEPROC, ShaderSource)                                     \
  ROPSIM_GL(PFNGLCOMPILESHADERPROC, CompileShader)                                   \
  ROPSIM_GL(PFNGLGETSHADERIVPROC, GetShaderiv)                                       \
  ROPSIM_GL(PFNGLGETSHADERINFOLOGPROC, GetShaderInfoLog)                             \
  ROPSIM_GL(PFNGLDELETESHADERPROC, DeleteShader)                                     \
  ROPSIM_GL(PFNGLCREATEPROGRAMPROC, CreateProgram)                                   \
  ROPSIM_GL(PFNGLATTACHSHADERPROC, AttachShader)                                     \
  ROPSIM_GL(PFNGLLINKPROGRAMPROC, LinkProgram)                                       \
  ROPSIM_GL(PFNGLGETPROGRAMIVPROC, GetProgramiv)                                     \
  ROPSIM_GL(PFNGLGETPROGRAMINFOLOGPROC, GetProgramInfoLog)                           \
  ROPSIM_GL(PFNGLUSEPROGRAMPROC, UseProgram)                                         \
  ROPSIM_GL(PFNGLDELETEPROGRAMPROC, DeleteProgram)                                   \
  ROPSIM_GL(PFNGLGETUNIFORMLOCATIONPROC, GetUniformLocation)                         \
  ROPSIM_GL(PFNGLUNIFORM1UIPROC, Uniform1ui)                                         \
  ROPSIM_GL(PFNGLGENBUFFERSPROC, GenBuffers)                                         \
  ROPSIM_GL(PFNGLBINDBUFFERPROC, BindBuffer)                                         \
  ROPSIM_GL(PFNGLBUFFERDATAPROC, BufferData)                                         \
  ROPSIM_GL(PFNGLBUFFERSUBDATAPROC, BufferSubData)                                   \
  ROPSIM_GL(PFNGLGETBUFFERSUBDATAPROC, GetBufferSubData)                             \
  ROPSIM_GL(PFNGLBINDBUFFERBASEPROC, BindBufferBase)                                 \
  ROPSIM_GL(PFNGLDELETEBUFFERSPROC, DeleteBuffers)                                   \
  ROPSIM_GL(PFNGLGENVERTEXARRAYSPROC, GenVertexArrays)                               \
  ROPSIM_GL(PFNGLBINDVERTEXARRAYPROC, BindVertexArray)                               \
  ROPSIM_GL(PFNGLDELETEVERTEXARRAYSPROC, DeleteVertexArrays)                         \
  ROPSIM_GL(PFNGLVERTEXATTRIBPOINTERPROC, VertexAttribPointer)                       \
  ROPSIM_GL(PFNGLENABLEVERTEXATTRIBARRAYPROC, EnableVertexAttribArray)               \
  ROPSIM_GL(PFNGLGETMULTISAMPLEFVPROC, GetMultisamplefv)                             \
  ROPSIM_GL(PFNGLMEMORYBARRIERPROC, MemoryBarrier)                                   \
  ROPSIM_GL(PFNGLCLIPCONTROLPROC, ClipControl)
  ROPSIM_GL_LIST
#undef ROPSIM_GL
  void load() {
#define ROPSIM_GL(type, name)                                      \
  name = reinterpret_cast<type>(OSMesaGetProcAddress("gl" #name)); \
  if (!name) throw CaptureError("Mesa cross-check: OSMesa has no gl" #name);
    ROPSIM_GL_LIST
#undef ROPSIM_GL
  }
};

const char* kVertexShader = R"(#version 450 core
layout(location = 0) in vec4 clip_position;
void main() { gl_Position = clip_position; }
)";

// One record per fragment shader invocation: pixel, draw, gl_PrimitiveID,
// gl_SampleMaskIn[0], gl_FragCoord.z. No depth test, no early tests: every
// fragment the rasterizer produces runs the shader.
const char* kFragmentShader = R"(#version 450 core
layout(std430, binding = 0) buffer Records { uint count; uint pad; uint rec[]; };
uniform uint draw_id;
uniform uint capacity;
layout(location = 0) out vec4 color;
void main() {
  if (!gl_HelperInvocation) {
    uint i = atomicAdd(count, 1u);
    if (i < capacity) {
      uint b = i * 5u;
      rec[b + 0u] = uint(gl_FragCoord.x) | (uint(gl_FragCoord.y) << 16);
      rec[b + 1u] = draw_id;
      rec[b + 2u] = uint(gl_PrimitiveID);
      rec[b + 3u] = uint(gl_SampleMaskIn[0]);
      rec[b + 4u] = floatBitsToUint(gl_FragCoord.z);
    }
  }
  color = vec4(1.0);
}
)";

class OsMesaContext {
 public:
  OsMesaContext(int w, int h) : buffer_(size_t(w) * size_t(h) * 4) {
    setenv("LP_NUM_THREADS", "2", 0);  // the machine is shared; respect a caller's setting
    const int attribs[] = {OSMESA_FORMAT,
                           OSMESA_RGBA,
                           OSMESA_DEPTH_BITS,
                           0,
                           OSMESA_STENCIL_BITS,
                           0,
                           OSMESA_PROFILE,
                           OSMESA_CORE_PROFILE,
                           OSMESA_CONTEXT_MAJOR_VERSION,
                           4,
                           OSMESA_CONTEXT_MINOR_VERSION,
                           5,
                           0};
    ctx_ = OSMesaCreateContextAttribs(attribs, nullptr);
    if (!ctx_) throw CaptureError("Mesa cross-check: OSMesa cannot create an OpenGL 4.5 core context");
    if (!OSMesaMakeCurrent(ctx_, buffer_.data(), GL_UNSIGNED_BYTE, w, h)) {
      OSMesaDestroyContext(ctx_);
      throw CaptureError("Mesa cross-check: OSMesaMakeCurrent failed");
    }
  }
  ~OsMesaContext() { OSMesaDestroyContext(ctx_); }
  OsMesaContext(const OsMesaContext&) = delete;
  OsMesaContext& operator=(const OsMesaContext&) = delete;

 private:
  std::vector<unsigned char> buffer_;
  OSMesaContext ctx_ = nullptr;
};

GLuint compile(const GlFunctions& gl, GLenum type, const char* src) {
  GLuint s = gl.CreateShader(type);
  gl.ShaderSource(s, 1, &src, nullptr);
  gl.CompileShader(s);
  GLint ok = 0;
  gl.GetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    gl.GetShaderInfoLog(s, sizeof log, nullptr, log);
    throw CaptureError(std::string("Mesa cross-check: shader does not compile: ") + log);
  }
  return s;
}

struct Key {
  uint32_t draw, prim;
  uint16_t y, x;
  bool operator<(const Key& o) const {
    return draw != o.draw ? draw < o.draw : prim != o.prim ? prim < o.prim : y != o.y ? y < o.y : x < o.x;
  }
  bool operator==(const Key& o) const { return draw == o.draw && prim == o.prim && y == o.y && x == o.x; }
};

}  // namespace

MesaCapture mesa_capture(const PreparedScene& ps, int samples) {
  const int W = int(ps.spec.width), H = int(ps.spec.height);
  OsMesaContext ctx(W, H);
  GlFunctions gl;
  gl.load();
  MesaCapture out;
  out.renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  out.version = reinterpret_cast<const char*>(glGetString(GL_VERSION));
  GLint major = 0, minor = 0;
  glGetIntegerv(GL_MAJOR_VERSION, &major);
  glGetIntegerv(GL_MINOR_VERSION, &minor);
  if (major * 10 + minor < 45) throw CaptureError("Mesa cross-check: need OpenGL 4.5, got " + out.version);

  GLuint fbo = 0, rb = 0;
  gl.GenFramebuffers(1, &fbo);
  gl.BindFramebuffer(GL_FRAMEBUFFER, fbo);
  gl.GenRenderbuffers(1, &rb);
  gl.BindRenderbuffer(GL_RENDERBUFFER, rb);
  gl.RenderbufferStorageMultisample(GL_RENDERBUFFER, samples, GL_RGBA8, W, H);
  gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rb);
  if (gl.CheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw CaptureError("Mesa cross-check: a " + std::to_string(samples) + "x multisampled framebuffer is not complete");
  glGetIntegerv(GL_SAMPLES, &out.samples);
  if (out.samples != samples)
    throw CaptureError("Mesa cross-check: asked for " + std::to_string(samples) + " samples, got " +
                       std::to_string(out.samples));
  for (int i = 0; i < samples; ++i) {
    std::array<float, 2> p{};
    gl.GetMultisamplefv(GL_SAMPLE_POSITION, GLuint(i), p.data());
    out.sample_positions.push_back(p);
  }
  // Depth 0..1 = z/w as in ropsim. The image is drawn upside down (clip y
  // negated, GL's lower-left origin), so that GL window y = trace row and
  // Mesa's fill rule, sample positions and gl_FragCoord are in trace
  // coordinates. (GL_UPPER_LEFT instead flips which horizontal edges own
  // their samples: docs/capture.md.)
  gl.ClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  glViewport(0, 0, W, H);
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_STENCIL_TEST);
  glDisable(GL_BLEND);
  glEnable(GL_MULTISAMPLE);
  glClearColor(0, 0, 0, 0);
  glClear(GL_COLOR_BUFFER_BIT);

  const GLuint vs = compile(gl, GL_VERTEX_SHADER, kVertexShader), fs = compile(gl, GL_FRAGMENT_SHADER, kFragmentShader);
  const GLuint prog = gl.CreateProgram();
  gl.AttachShader(prog, vs);
  gl.AttachShader(prog, fs);
  gl.LinkProgram(prog);
  GLint linked = 0;
  gl.GetProgramiv(prog, GL_LINK_STATUS, &linked);
  if (!linked) {
    char log[2048] = {};
    gl.GetProgramInfoLog(prog, sizeof log, nullptr, log);
    throw CaptureError(std::string("Mesa cross-check: program does not link: ") + log);
  }
  gl.UseProgram(prog);
  const GLint loc_draw = gl.GetUniformLocation(prog, "draw_id"), loc_cap = gl.GetUniformLocation(prog, "capacity");

  GLuint vao = 0, vbo = 0, ssbo = 0;
  gl.GenVertexArrays(1, &vao);
  gl.BindVertexArray(vao);
  gl.GenBuffers(1, &vbo);
  gl.GenBuffers(1, &ssbo);

  // Capacity: grows and the scene is redrawn if the first pass overflowed.
  uint64_t capacity = uint64_t(W) * uint64_t(H) * 8;
  std::vector<uint32_t> raw;
  for (int pass = 0; pass < 2; ++pass) {
    const size_t bytes = 8 + size_t(capacity) * 20;
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, ssbo);
    gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(bytes), nullptr, GL_DYNAMIC_READ);
    const uint32_t zero[2] = {0, 0};
    gl.BufferSubData(GL_SHADER_STORAGE_BUFFER, 0, sizeof zero, zero);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, ssbo);
    gl.Uniform1ui(loc_cap, GLuint(capacity));
    for (uint32_t di = 0; di < ps.draws.size(); ++di) {
      const PreparedDraw& d = ps.draws[di];
      std::vector<float> verts;
      verts.reserve(d.triangles.size() * 12);
      for (const ClipTriangle& t : d.triangles)
        for (const ClipVertex& v : t.v)
          for (int c = 0; c < 4; ++c)  // discarded: no area
            verts.push_back(t.discarded ? 0.0f : c == 1 ? -v.pos[1] : v.pos[size_t(c)]);
      gl.BindBuffer(GL_ARRAY_BUFFER, vbo);
      gl.BufferData(GL_ARRAY_BUFFER, GLsizeiptr(verts.size() * sizeof(float)), verts.data(), GL_STATIC_DRAW);
      gl.VertexAttribPointer(0, 4, GL_FLOAT, GL_FALSE, 0, nullptr);
      gl.EnableVertexAttribArray(0);
      gl.Uniform1ui(loc_draw, di);
      if (d.back_faces) {
        glDisable(GL_CULL_FACE);
      } else {
        glEnable(GL_CULL_FACE);
        glCullFace(GL_BACK);
        glFrontFace(GL_CW);  // counter-clockwise before the y flip
      }
      glDrawArrays(GL_TRIANGLES, 0, GLsizei(d.triangles.size() * 3));
    }
    gl.MemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT);
    glFinish();
    uint32_t count = 0;
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, ssbo);
    gl.GetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, 4, &count);
    if (count <= capacity) {
      raw.resize(size_t(count) * 5);
      if (count) gl.GetBufferSubData(GL_SHADER_STORAGE_BUFFER, 8, GLsizeiptr(raw.size() * 4), raw.data());
      out.invocations = count;
      break;
    }
    if (pass == 1) throw CaptureError("Mesa cross-check: the record buffer overflowed twice");
    capacity = count;
    gl.BindFramebuffer(GL_FRAMEBUFFER, fbo);
  }
  gl.DeleteBuffers(1, &vbo);
  gl.DeleteBuffers(1, &ssbo);
  gl.DeleteVertexArrays(1, &vao);
  gl.DeleteProgram(prog);
  gl.DeleteShader(vs);
  gl.DeleteShader(fs);
  gl.DeleteRenderbuffers(1, &rb);
  gl.DeleteFramebuffers(1, &fbo);
  if (GLenum e = glGetError(); e != GL_NO_ERROR)
    throw CaptureError(fmt::format("Mesa cross-check: OpenGL error 0x{:x}", e));

  // API order: (draw, primitive, y, x); invocations of one primitive at one
  // pixel (a primitive split by Mesa's clipper) are merged.
  std::vector<MesaRecord> recs(out.invocations);
  for (size_t i = 0; i < recs.size(); ++i) {
    const uint32_t* r = &raw[i * 5];
    recs[i].x = uint16_t(r[0] & 0xFFFF);
    recs[i].y = uint16_t(r[0] >> 16);
    recs[i].draw = r[1];
    recs[i].prim = r[2];
    recs[i].mask = r[3];
    std::memcpy(&recs[i].z, &r[4], 4);
  }
  std::stable_sort(recs.begin(), recs.end(), [](const MesaRecord& a, const MesaRecord& b) {
    return Key{a.draw, a.prim, a.y, a.x} < Key{b.draw, b.prim, b.y, b.x};
  });
  for (const MesaRecord& r : recs) {
    if (!out.records.empty()) {
      MesaRecord& last = out.records.back();
      if (last.draw == r.draw && last.prim == r.prim && last.x == r.x && last.y == r.y) {
        last.mask |= r.mask;
        continue;
      }
    }
    out.records.push_back(r);
  }
  return out;
}

CrossCheckResult cross_check_with_mesa(const SceneSpec& spec_in) {
  SceneSpec spec = spec_in;
  spec.spp = 4;
  const PreparedScene ps = prepare_scene(spec);
  CrossCheckResult r;
  r.scene = spec.name;
  r.width = spec.width;
  r.height = spec.height;
  r.samples = 4;
  auto t0 = std::chrono::steady_clock::now();
  const MesaCapture mc = mesa_capture(ps, 4);
  r.mesa_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.renderer = mc.renderer + " / " + mc.version;

  TraceHeader h = capture_header(spec);
  for (int i = 0; i < 4; ++i) {
    const double x = mc.sample_positions[size_t(i)][0] * 256, y = mc.sample_positions[size_t(i)][1] * 256;
    if (x != std::floor(x) || y != std::floor(y) || x < 0 || x > 255 || y < 0 || y > 255)
      throw CaptureError(fmt::format("Mesa cross-check: sample {} at ({}, {}) is not on the 1/256 pixel grid", i,
                                     mc.sample_positions[size_t(i)][0], mc.sample_positions[size_t(i)][1]));
    h.positions[size_t(i)] = SamplePos{uint8_t(x), uint8_t(y)};
    r.positions += fmt::format("{}({},{})", i ? " " : "", int(x), int(y));
  }
  t0 = std::chrono::steady_clock::now();
  struct Rec {  // the fields compared (a Fragment holds 64 sample depths)
    uint32_t draw_id, prim_id;
    uint16_t x, y;
    uint64_t coverage;
    float z0, dzdx, dzdy;
  };
  std::vector<Rec> ours;
  rasterize_prepared(ps, h, [&](const Fragment& f) {
    ours.push_back(Rec{f.draw_id, f.prim_id, f.x, f.y, f.coverage, f.z0, f.dzdx, f.dzdy});
  });
  r.ours_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.ours = ours.size();
  r.mesa = mc.records.size();

  // Distance of a sample from the nearest edge of ropsim's snapped triangle.
  const double g = std::ldexp(1.0, 21) / double(std::max(h.width, h.height));
  auto classify = [&](uint32_t draw, uint32_t prim, int px, int py, int s) {
    ++r.samples_differ;
    if (draw >= ps.draws.size() || prim >= ps.draws[draw].triangles.size()) {  // an id ropsim never submitted
      ++r.farther;
      return;
    }
    const ClipTriangle& t = ps.draws[draw].triangles[prim];
    int64_t X[3], Y[3];
    for (int k = 0; k < 3; ++k) {
      const auto& p = t.v[size_t(k)].pos;
      const double w = p[3];
      if (!(p[2] >= 0 && p[2] <= w && std::abs(p[0]) <= g * w && std::abs(p[1]) <= g * w)) {
        ++r.in_clipped;
        return;
      }
      const double iw = 1.0 / w;
      X[k] = std::llround((p[0] * iw * 0.5 + 0.5) * double(h.width) * 256);
      Y[k] = std::llround((0.5 - 0.5 * p[1] * iw) * double(h.height) * 256);
    }
    const int64_t sx = int64_t(px) * 256 + h.positions[size_t(s)].x, sy = int64_t(py) * 256 + h.positions[size_t(s)].y;
    double best = 1e300;
    bool tie = false;
    for (int e = 0; e < 3; ++e) {
      const int n = (e + 1) % 3;
      const int64_t ex = X[n] - X[e], ey = Y[n] - Y[e];
      const int64_t f = ex * (sy - Y[e]) - ey * (sx - X[e]);
      const double len = std::sqrt(double(ex) * double(ex) + double(ey) * double(ey));
      if (f == 0 && len > 0) tie = true;
      if (len > 0) best = std::min(best, std::abs(double(f)) / len);
    }
    if (tie)
      ++r.on_edge;
    else if (best <= 1.0)
      ++r.within_one_subpixel;
    else
      ++r.farther;
  };
  auto diff_mask = [&](uint32_t draw, uint32_t prim, int px, int py, uint64_t m) {
    for (; m; m &= m - 1) classify(draw, prim, px, py, __builtin_ctzll(m));
  };

  // Both lists are in (draw, prim, y, x) order: merge.
  size_t i = 0, j = 0;
  double depth_sum = 0;
  while (i < ours.size() || j < mc.records.size()) {
    const bool have_o = i < ours.size(), have_m = j < mc.records.size();
    const Key ko = have_o ? Key{ours[i].draw_id, ours[i].prim_id, ours[i].y, ours[i].x} : Key{};
    const Key km = have_m ? Key{mc.records[j].draw, mc.records[j].prim, mc.records[j].y, mc.records[j].x} : Key{};
    if (have_o && (!have_m || ko < km)) {
      ++r.only_ours;
      diff_mask(ko.draw, ko.prim, ko.x, ko.y, ours[i].coverage);
      ++i;
    } else if (have_m && (!have_o || km < ko)) {
      ++r.only_mesa;
      diff_mask(km.draw, km.prim, km.x, km.y, mc.records[j].mask);
      ++j;
    } else {
      if (ours[i].coverage == mc.records[j].mask)
        ++r.equal;
      else {
        ++r.mask_differs;
        diff_mask(ko.draw, ko.prim, ko.x, ko.y, ours[i].coverage ^ mc.records[j].mask);
      }
      // The depths the ROP uses: clamped to [0, 1] (docs/trace-format.md section 4).
      const double dz =
          std::abs(std::clamp(double(ours[i].z0), 0.0, 1.0) - std::clamp(double(mc.records[j].z), 0.0, 1.0));
      r.max_depth_diff = std::max(r.max_depth_diff, dz);
      depth_sum += dz;
      if (dz > kDepthTolAbs + kDepthTolPixels * (std::abs(double(ours[i].dzdx)) + std::abs(double(ours[i].dzdy))))
        ++r.depth_over_tolerance;
      ++i;
      ++j;
    }
  }
  const uint64_t both = r.equal + r.mask_differs;
  const uint64_t uni = both + r.only_ours + r.only_mesa;
  r.agreement = uni ? double(r.equal) / double(uni) : 1.0;
  r.mean_depth_diff = both ? depth_sum / double(both) : 0.0;
  return r;
}

std::string cross_check_summary(const CrossCheckResult& r) {
  std::string s;
  s += fmt::format("cross-check {} at {}x{}, {} spp against {}\n", r.scene, r.width, r.height, r.samples, r.renderer);
  s += fmt::format("  sample positions (1/256 pixel from the top-left corner): {}\n", r.positions);
  s += fmt::format(
      "  records (draw, primitive, pixel): ropsim {}, Mesa {}; equal {} ({:.4f}%), mask differs {}, "
      "only ropsim {}, only Mesa {}\n",
      r.ours, r.mesa, r.equal, 100.0 * r.agreement, r.mask_differs, r.only_ours, r.only_mesa);
  s += fmt::format(
      "  samples covered by one rasterizer only: {} (on an edge of ropsim's snapped triangle {}, within "
      "1/256 pixel of one {}, farther {}, in clipped triangles {})\n",
      r.samples_differ, r.on_edge, r.within_one_subpixel, r.farther, r.in_clipped);
  s += fmt::format(
      "  depth at the pixel centre, clamped to [0, 1]: max |diff| {:.3g}, mean {:.3g}; over the tolerance "
      "({:g} + {:g} px x |gradient|): {}\n",
      r.max_depth_diff, r.mean_depth_diff, kDepthTolAbs, kDepthTolPixels, r.depth_over_tolerance);
  s += fmt::format("  time: ropsim {:.3f} s, Mesa {:.3f} s\n", r.ours_seconds, r.mesa_seconds);
  return s;
}

}  // namespace ropsim
