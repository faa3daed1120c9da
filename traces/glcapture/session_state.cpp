#include "traces/glcapture/session_state.h"

#include <GL/glx.h>

#include <algorithm>
#include <cstdio>

namespace ropsim::glcapture {

namespace {

bool map_factor(GLint v, BlendFactor& f) {
  switch (v) {
    case GL_ZERO:
      f = BlendFactor::kZero;
      return true;
    case GL_ONE:
      f = BlendFactor::kOne;
      return true;
    case GL_SRC_COLOR:
      f = BlendFactor::kSrcColor;
      return true;
    case GL_ONE_MINUS_SRC_COLOR:
      f = BlendFactor::kOneMinusSrcColor;
      return true;
    case GL_DST_COLOR:
      f = BlendFactor::kDstColor;
      return true;
    case GL_ONE_MINUS_DST_COLOR:
      f = BlendFactor::kOneMinusDstColor;
      return true;
    case GL_SRC_ALPHA:
      f = BlendFactor::kSrcAlpha;
      return true;
    case GL_ONE_MINUS_SRC_ALPHA:
      f = BlendFactor::kOneMinusSrcAlpha;
      return true;
    case GL_DST_ALPHA:
      f = BlendFactor::kDstAlpha;
      return true;
    case GL_ONE_MINUS_DST_ALPHA:
      f = BlendFactor::kOneMinusDstAlpha;
      return true;
    case GL_CONSTANT_COLOR:
      f = BlendFactor::kConstantColor;
      return true;
    case GL_ONE_MINUS_CONSTANT_COLOR:
      f = BlendFactor::kOneMinusConstantColor;
      return true;
    case GL_CONSTANT_ALPHA:
      f = BlendFactor::kConstantAlpha;
      return true;
    case GL_ONE_MINUS_CONSTANT_ALPHA:
      f = BlendFactor::kOneMinusConstantAlpha;
      return true;
    case GL_SRC_ALPHA_SATURATE:
      f = BlendFactor::kSrcAlphaSaturate;
      return true;
    default:
      return false;  // the dual-source factors (GL_SRC1_*)
  }
}

bool map_equation(GLint v, BlendEquation& e) {
  switch (v) {
    case GL_FUNC_ADD:
      e = BlendEquation::kAdd;
      return true;
    case GL_FUNC_SUBTRACT:
      e = BlendEquation::kSubtract;
      return true;
    case GL_FUNC_REVERSE_SUBTRACT:
      e = BlendEquation::kReverseSubtract;
      return true;
    case GL_MIN:
      e = BlendEquation::kMin;
      return true;
    case GL_MAX:
      e = BlendEquation::kMax;
      return true;
    default:
      return false;  // the advanced blend equations (KHR_blend_equation_advanced)
  }
}

DepthFunc map_depth_func(GLint v) {
  switch (v) {
    case GL_NEVER:
      return DepthFunc::kNever;
    case GL_LESS:
      return DepthFunc::kLess;
    case GL_EQUAL:
      return DepthFunc::kEqual;
    case GL_LEQUAL:
      return DepthFunc::kLequal;
    case GL_GREATER:
      return DepthFunc::kGreater;
    case GL_NOTEQUAL:
      return DepthFunc::kNotequal;
    case GL_GEQUAL:
      return DepthFunc::kGequal;
    default:
      return DepthFunc::kAlways;
  }
}

std::string hex(GLint v) {
  char b[16];
  std::snprintf(b, sizeof b, "0x%04X", unsigned(v));
  return b;
}

}  // namespace

std::string blend_text(const DrawState& s) {
  if (!s.blend) return "off";
  return std::string(to_string(s.eq_rgb)) + "(" + to_string(s.src_rgb) + ", " + to_string(s.dst_rgb) + "), " +
         to_string(s.eq_alpha) + "(" + to_string(s.src_alpha) + ", " + to_string(s.dst_alpha) + ")";
}

std::string depth_text(const DrawState& s) {
  if (!s.depth_test) return "off";
  return std::string(to_string(s.depth_func)) + (s.depth_write ? ", write" : ", no write");
}

const char* encoding_name(TargetEncoding e) {
  switch (e) {
    case TargetEncoding::kUnorm8:
      return "unorm8";
    case TargetEncoding::kSrgb8:
      return "srgb8";
    default:
      return "float";
  }
}

FramebufferInfo query_framebuffer(GLint fbo) {
  const GlFunctions& g = real_gl();
  FramebufferInfo f;
  f.fbo = fbo;
  GLint type = GL_NONE, name = 0, encoding = GL_LINEAR, component = GL_UNSIGNED_NORMALIZED;
  if (fbo == 0) {
    f.name = "presented";
    f.presented = true;
    GLint bound = 0;
    g.GetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &bound);
    if (bound != 0) g.BindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
    GLboolean doublebuffer = GL_TRUE;
    g.GetBooleanv(GL_DOUBLEBUFFER, &doublebuffer);
    const GLenum colour = doublebuffer ? GL_BACK_LEFT : GL_FRONT_LEFT;
    g.GetFramebufferAttachmentParameteriv(GL_DRAW_FRAMEBUFFER, colour, GL_FRAMEBUFFER_ATTACHMENT_COLOR_ENCODING,
                                          &encoding);
    g.GetFramebufferAttachmentParameteriv(GL_DRAW_FRAMEBUFFER, colour, GL_FRAMEBUFFER_ATTACHMENT_COMPONENT_TYPE,
                                          &component);
    GLint depth_bits = 0;
    g.GetFramebufferAttachmentParameteriv(GL_DRAW_FRAMEBUFFER, GL_DEPTH, GL_FRAMEBUFFER_ATTACHMENT_DEPTH_SIZE,
                                          &depth_bits);
    f.has_depth = depth_bits > 0;
    GLint stencil_bits = 0;
    g.GetFramebufferAttachmentParameteriv(GL_DRAW_FRAMEBUFFER, GL_STENCIL, GL_FRAMEBUFFER_ATTACHMENT_STENCIL_SIZE,
                                          &stencil_bits);
    f.has_stencil = stencil_bits > 0;
    g.GetIntegerv(GL_SAMPLES, &f.samples);
    // The drawable's size from the window system; the viewport otherwise.
    unsigned w = 0, h = 0;
    if (g.glXGetCurrentContext && g.glXGetCurrentContext() && g.glXQueryDrawable) {
      g.glXQueryDrawable(g.glXGetCurrentDisplay(), g.glXGetCurrentDrawable(), GLX_WIDTH, &w);
      g.glXQueryDrawable(g.glXGetCurrentDisplay(), g.glXGetCurrentDrawable(), GLX_HEIGHT, &h);
    } else if (g.eglGetCurrentContext && g.eglGetCurrentContext() != EGL_NO_CONTEXT && g.eglQuerySurface) {
      EGLint ew = 0, eh = 0;
      g.eglQuerySurface(g.eglGetCurrentDisplay(), g.eglGetCurrentSurface(EGL_DRAW), EGL_WIDTH, &ew);
      g.eglQuerySurface(g.eglGetCurrentDisplay(), g.eglGetCurrentSurface(EGL_DRAW), EGL_HEIGHT, &eh);
      w = unsigned(ew);
      h = unsigned(eh);
    }
    if (w == 0 || h == 0) {
      GLint vp[4] = {};
      g.GetIntegerv(GL_VIEWPORT, vp);
      w = unsigned(vp[2]);
      h = unsigned(vp[3]);
    }
    f.width = int(w);
    f.height = int(h);
    if (bound != 0) g.BindFramebuffer(GL_DRAW_FRAMEBUFFER, GLuint(bound));
  } else {
    f.name = "fbo " + std::to_string(fbo);
    const GLuint fb = GLuint(fbo);
    g.GetNamedFramebufferAttachmentParameteriv(fb, GL_COLOR_ATTACHMENT0, GL_FRAMEBUFFER_ATTACHMENT_OBJECT_TYPE, &type);
    if (type != GL_NONE) {
      g.GetNamedFramebufferAttachmentParameteriv(fb, GL_COLOR_ATTACHMENT0, GL_FRAMEBUFFER_ATTACHMENT_OBJECT_NAME,
                                                 &name);
      g.GetNamedFramebufferAttachmentParameteriv(fb, GL_COLOR_ATTACHMENT0, GL_FRAMEBUFFER_ATTACHMENT_COLOR_ENCODING,
                                                 &encoding);
      g.GetNamedFramebufferAttachmentParameteriv(fb, GL_COLOR_ATTACHMENT0, GL_FRAMEBUFFER_ATTACHMENT_COMPONENT_TYPE,
                                                 &component);
    }
    if (type == GL_TEXTURE) {
      GLint level = 0;
      g.GetNamedFramebufferAttachmentParameteriv(fb, GL_COLOR_ATTACHMENT0, GL_FRAMEBUFFER_ATTACHMENT_TEXTURE_LEVEL,
                                                 &level);
      g.GetTextureLevelParameteriv(GLuint(name), level, GL_TEXTURE_WIDTH, &f.width);
      g.GetTextureLevelParameteriv(GLuint(name), level, GL_TEXTURE_HEIGHT, &f.height);
      g.GetTextureLevelParameteriv(GLuint(name), level, GL_TEXTURE_SAMPLES, &f.samples);
    } else if (type == GL_RENDERBUFFER) {
      g.GetNamedRenderbufferParameteriv(GLuint(name), GL_RENDERBUFFER_WIDTH, &f.width);
      g.GetNamedRenderbufferParameteriv(GLuint(name), GL_RENDERBUFFER_HEIGHT, &f.height);
      g.GetNamedRenderbufferParameteriv(GLuint(name), GL_RENDERBUFFER_SAMPLES, &f.samples);
    }
    GLint depth_type = GL_NONE;
    g.GetNamedFramebufferAttachmentParameteriv(fb, GL_DEPTH_ATTACHMENT, GL_FRAMEBUFFER_ATTACHMENT_OBJECT_TYPE,
                                               &depth_type);
    f.has_depth = depth_type != GL_NONE;
    GLint stencil_type = GL_NONE;
    g.GetNamedFramebufferAttachmentParameteriv(fb, GL_STENCIL_ATTACHMENT, GL_FRAMEBUFFER_ATTACHMENT_OBJECT_TYPE,
                                               &stencil_type);
    f.has_stencil = stencil_type != GL_NONE;
  }
  if (component == GL_FLOAT)
    f.encoding = TargetEncoding::kFloat;
  else if (encoding == GL_SRGB && g.IsEnabled(GL_FRAMEBUFFER_SRGB))
    f.encoding = TargetEncoding::kSrgb8;
  else
    f.encoding = TargetEncoding::kUnorm8;
  return f;
}

DrawState read_draw_state(uint32_t index, const FramebufferInfo& fb, std::string& unsupported) {
  const GlFunctions& g = real_gl();
  DrawState s;
  s.draw_id = index;
  s.blend = g.IsEnabledi(GL_BLEND, 0);
  GLint v[6] = {};
  g.GetIntegerv(GL_BLEND_EQUATION_RGB, &v[0]);
  g.GetIntegerv(GL_BLEND_EQUATION_ALPHA, &v[1]);
  g.GetIntegerv(GL_BLEND_SRC_RGB, &v[2]);
  g.GetIntegerv(GL_BLEND_DST_RGB, &v[3]);
  g.GetIntegerv(GL_BLEND_SRC_ALPHA, &v[4]);
  g.GetIntegerv(GL_BLEND_DST_ALPHA, &v[5]);
  if (!map_equation(v[0], s.eq_rgb) || !map_equation(v[1], s.eq_alpha))
    unsupported = "blend equation " + hex(map_equation(v[0], s.eq_rgb) ? v[1] : v[0]) + " has no trace equivalent";
  BlendFactor* f[4] = {&s.src_rgb, &s.dst_rgb, &s.src_alpha, &s.dst_alpha};
  for (int i = 0; i < 4; ++i)
    if (!map_factor(v[2 + i], *f[i]) && s.blend)
      unsupported = "blend factor " + hex(v[2 + i]) + " (dual-source) has no trace equivalent";
  g.GetFloatv(GL_BLEND_COLOR, s.blend_color.data());
  s.depth_test = fb.has_depth && g.IsEnabled(GL_DEPTH_TEST);
  GLint func = GL_LESS;
  g.GetIntegerv(GL_DEPTH_FUNC, &func);
  s.depth_func = map_depth_func(func);
  GLboolean mask = GL_TRUE;
  g.GetBooleanv(GL_DEPTH_WRITEMASK, &mask);
  s.depth_write = s.depth_test && mask;
  GLboolean cm[4] = {GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE};
  g.GetBooleani_v(GL_COLOR_WRITEMASK, 0, cm);
  s.color_mask = uint8_t((cm[0] ? 1 : 0) | (cm[1] ? 2 : 0) | (cm[2] ? 4 : 0) | (cm[3] ? 8 : 0));
  s.encoding = fb.encoding;
  if (!fb.has_depth) s.depth_func = DepthFunc::kAlways;
  if (unsupported.empty() && fb.has_stencil && g.IsEnabled(GL_STENCIL_TEST))
    unsupported = "the stencil test has no trace equivalent";
  return s;
}

}  // namespace ropsim::glcapture
