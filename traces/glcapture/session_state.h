// The GL state the capture reads and changes (docs/capture.md "One draw"):
// a framebuffer's description, a draw's state for the trace, and the state
// a capture pass or the 4x reference draw changes, saved and restored. GL
// calls through real_gl() only. Private to the capture library.
#pragma once
#include <GL/gl.h>

#include <array>
#include <cstdint>
#include <string>

#include "traces/format/draw_state.h"
#include "traces/glcapture/gl_functions.h"
#include "traces/glcapture/glsl_rewrite.h"

namespace ropsim::glcapture {

struct FramebufferInfo {
  std::string name;
  GLint fbo = 0;
  int width = 0, height = 0, samples = 0;
  TargetEncoding encoding = TargetEncoding::kUnorm8;
  bool has_depth = false, has_stencil = false, presented = false;
  int draws = 0;
};

const char* encoding_name(TargetEncoding e);
/// A draw state's blend and depth test in words (list.json).
std::string blend_text(const DrawState& s);
std::string depth_text(const DrawState& s);

/// The framebuffer `fbo` (0: the presented one) as GL describes it now.
FramebufferInfo query_framebuffer(GLint fbo);

/// The current draw state for the trace's draw `index` into `fb`;
/// `unsupported` set to why it has no trace equivalent, if it has none.
DrawState read_draw_state(uint32_t index, const FramebufferInfo& fb, std::string& unsupported);

/// The storage buffer bindings the capture's buffers take, restored after them.
struct SavedBindings {
  GLint generic = 0;
  std::array<GLint, kCaptureBindings> buffer{};
  std::array<GLint64, kCaptureBindings> start{}, size{};

  void save(GLint binding) {
    const GlFunctions& g = real_gl();
    g.GetIntegerv(GL_SHADER_STORAGE_BUFFER_BINDING, &generic);
    for (int k = 0; k < kCaptureBindings; ++k) {
      const GLuint i = GLuint(binding + k);
      g.GetIntegeri_v(GL_SHADER_STORAGE_BUFFER_BINDING, i, &buffer[size_t(k)]);
      g.GetInteger64i_v(GL_SHADER_STORAGE_BUFFER_START, i, &start[size_t(k)]);
      g.GetInteger64i_v(GL_SHADER_STORAGE_BUFFER_SIZE, i, &size[size_t(k)]);
    }
  }
  void restore(GLint binding) const {
    const GlFunctions& g = real_gl();
    for (int k = 0; k < kCaptureBindings; ++k) {
      const GLuint i = GLuint(binding + k);
      const size_t j = size_t(k);
      if (size[j] > 0)
        g.BindBufferRange(GL_SHADER_STORAGE_BUFFER, i, GLuint(buffer[j]), GLintptr(start[j]), GLsizeiptr(size[j]));
      else
        g.BindBufferBase(GL_SHADER_STORAGE_BUFFER, i, GLuint(buffer[j]));
    }
    g.BindBuffer(GL_SHADER_STORAGE_BUFFER, GLuint(generic));
  }
};

/// The stencil state of each face, in SavedState::stencil's order.
constexpr GLenum kStencilState[2][7] = {
    {GL_STENCIL_FUNC, GL_STENCIL_REF, GL_STENCIL_VALUE_MASK, GL_STENCIL_FAIL, GL_STENCIL_PASS_DEPTH_FAIL,
     GL_STENCIL_PASS_DEPTH_PASS, GL_STENCIL_WRITEMASK},
    {GL_STENCIL_BACK_FUNC, GL_STENCIL_BACK_REF, GL_STENCIL_BACK_VALUE_MASK, GL_STENCIL_BACK_FAIL,
     GL_STENCIL_BACK_PASS_DEPTH_FAIL, GL_STENCIL_BACK_PASS_DEPTH_PASS, GL_STENCIL_BACK_WRITEMASK}};

/// The GL state a capture pass changes, restored after it.
struct SavedState {
  GLint program = 0, draw_fbo = 0;
  SavedBindings bindings;
  GLboolean depth_test = GL_FALSE, stencil_test = GL_FALSE, scissor_test = GL_FALSE;
  /// Per face (front, back): function, reference, value mask, the three
  /// operations, write mask.
  GLint stencil[2][7] = {};
  GLint depth_func = GL_LESS;
  GLboolean depth_mask = GL_TRUE;
  GLint draw_buffers = 1;
  GLboolean blend[16] = {};
  GLboolean mask[16][4] = {};

  void save(GLint binding) {
    const GlFunctions& g = real_gl();
    g.GetIntegerv(GL_CURRENT_PROGRAM, &program);
    g.GetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &draw_fbo);
    bindings.save(binding);
    depth_test = g.IsEnabled(GL_DEPTH_TEST);
    stencil_test = g.IsEnabled(GL_STENCIL_TEST);
    scissor_test = g.IsEnabled(GL_SCISSOR_TEST);
    g.GetIntegerv(GL_DEPTH_FUNC, &depth_func);
    g.GetBooleanv(GL_DEPTH_WRITEMASK, &depth_mask);
    for (int f = 0; f < 2; ++f)
      for (int k = 0; k < 7; ++k) g.GetIntegerv(kStencilState[f][k], &stencil[f][k]);
    g.GetIntegerv(GL_MAX_DRAW_BUFFERS, &draw_buffers);
    draw_buffers = std::min(16, std::max(1, draw_buffers));
    for (GLint i = 0; i < draw_buffers; ++i) {
      blend[i] = g.IsEnabledi(GL_BLEND, GLuint(i));
      g.GetBooleani_v(GL_COLOR_WRITEMASK, GLuint(i), mask[i]);
    }
  }
  void restore(GLint binding) const {
    const GlFunctions& g = real_gl();
    g.UseProgram(GLuint(program));
    g.BindFramebuffer(GL_DRAW_FRAMEBUFFER, GLuint(draw_fbo));
    bindings.restore(binding);
    (depth_test ? g.Enable : g.Disable)(GL_DEPTH_TEST);
    (stencil_test ? g.Enable : g.Disable)(GL_STENCIL_TEST);
    (scissor_test ? g.Enable : g.Disable)(GL_SCISSOR_TEST);
    g.DepthFunc(GLenum(depth_func));
    g.DepthMask(depth_mask);
    for (int f = 0; f < 2; ++f) {
      const GLenum face = f ? GL_BACK : GL_FRONT;
      const GLint* v = stencil[f];
      g.StencilFuncSeparate(face, GLenum(v[0]), v[1], GLuint(v[2]));
      g.StencilOpSeparate(face, GLenum(v[3]), GLenum(v[4]), GLenum(v[5]));
      g.StencilMaskSeparate(face, GLuint(v[6]));
    }
    for (GLint i = 0; i < draw_buffers; ++i) {
      (blend[i] ? g.Enablei : g.Disablei)(GL_BLEND, GLuint(i));
      g.ColorMaski(GLuint(i), mask[i][0], mask[i][1], mask[i][2], mask[i][3]);
    }
  }
};

/// The GL state the upside-down reference draw changes, restored after it.
struct FlippedState {
  GLint viewport[4] = {}, scissor[4] = {}, front_face = GL_CCW, draw_fbo = 0;

  void flip(GLuint fbo, int height) {
    const GlFunctions& g = real_gl();
    g.GetIntegerv(GL_VIEWPORT, viewport);
    g.GetIntegerv(GL_SCISSOR_BOX, scissor);
    g.GetIntegerv(GL_FRONT_FACE, &front_face);
    g.GetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &draw_fbo);
    g.BindFramebuffer(GL_DRAW_FRAMEBUFFER, fbo);
    g.Viewport(viewport[0], height - viewport[1] - viewport[3], viewport[2], viewport[3]);
    g.Scissor(scissor[0], height - scissor[1] - scissor[3], scissor[2], scissor[3]);
    g.FrontFace(front_face == GL_CCW ? GL_CW : GL_CCW);  // the y flip mirrors the winding
  }
  void restore() const {
    const GlFunctions& g = real_gl();
    g.Viewport(viewport[0], viewport[1], viewport[2], viewport[3]);
    g.Scissor(scissor[0], scissor[1], scissor[2], scissor[3]);
    g.FrontFace(GLenum(front_face));
    g.BindFramebuffer(GL_DRAW_FRAMEBUFFER, GLuint(draw_fbo));
  }
};

}  // namespace ropsim::glcapture
