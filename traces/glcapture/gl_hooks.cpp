// The entry points libropsim_glcapture.so exports: the application's calls
// (linked directly, looked up with glXGetProcAddress(ARB) / eglGetProcAddress,
// or with dlsym on a handle from dlopen("libGL.so.1"), which returns this
// library) reach these wrappers, which forward to the real ones and tell the
// capture session (capture_session.h). Without ROPSIM_GL_CONTROL they only
// forward.
#include <dlfcn.h>

#include <cstring>
#include <string>

#include "traces/glcapture/capture_session.h"
#include "traces/glcapture/gl_functions.h"

#define ROPSIM_EXPORT extern "C" __attribute__((visibility("default")))

namespace ropsim::glcapture {

namespace {

using DlopenFn = void* (*)(const char*, int);

DlopenFn real_dlopen() {
  static DlopenFn f = reinterpret_cast<DlopenFn>(dlsym(RTLD_NEXT, "dlopen"));
  return f;
}

/// This library's own path (for the handle dlopen("libGL.so.1") returns).
const char* own_path() {
  static std::string path = [] {
    Dl_info info{};
    if (dladdr(reinterpret_cast<void*>(&own_path), &info) && info.dli_fname) return std::string(info.dli_fname);
    return std::string();
  }();
  return path.c_str();
}

/// The libraries whose handle is this library's: their GL entry points
/// then resolve to the wrappers, the others to this library's dependencies
/// (libGL, libEGL).
bool is_gl_library(const char* filename) {
  const char* base = std::strrchr(filename, '/');
  base = base ? base + 1 : filename;
  return std::strncmp(base, "libGL.so", 8) == 0 || std::strncmp(base, "libEGL.so", 9) == 0 ||
         std::strncmp(base, "libOpenGL.so", 12) == 0;
}

template <typename F>
F resolve(const char* name) {
  return reinterpret_cast<F>(real_proc_address(name));
}

GlFunctions load_functions() {
  GlFunctions g;
  // The window-system ones first: glXGetProcAddressARB resolves the rest.
#define ROPSIM_RESOLVE_WS(type, name) g.name = reinterpret_cast<type>(dlsym(RTLD_NEXT, #name));
  ROPSIM_WS_ENTRY_POINTS(ROPSIM_RESOLVE_WS)
#undef ROPSIM_RESOLVE_WS
  return g;
}

GlFunctions& functions() {
  static GlFunctions g = load_functions();
  return g;
}

bool g_loaded = false;

}  // namespace

void* real_proc_address(const char* name) {
  if (void* p = dlsym(RTLD_NEXT, name)) return p;
  const GlFunctions& g = functions();
  if (std::strncmp(name, "gl", 2) == 0 && g.glXGetProcAddressARB)
    if (auto p = g.glXGetProcAddressARB(reinterpret_cast<const GLubyte*>(name))) return reinterpret_cast<void*>(p);
  if (g.eglGetProcAddress)
    if (auto p = g.eglGetProcAddress(name)) return reinterpret_cast<void*>(p);
  return nullptr;
}

const GlFunctions& real_gl() {
  GlFunctions& g = functions();
  if (!g_loaded) {
    g_loaded = true;
#define ROPSIM_RESOLVE_GL(type, name) g.name = resolve<type>("gl" #name);
    ROPSIM_GL_ENTRY_POINTS(ROPSIM_RESOLVE_GL)
#undef ROPSIM_RESOLVE_GL
  }
  return g;
}

namespace {

CaptureSession* active() {
  CaptureSession* s = session();
  return s && s->capturing() ? s : nullptr;
}

/// A draw: forwarded; during frame N also re-executed (no std::function is
/// made outside frame N).
template <typename Call>
void draw(const Call& call, uint32_t prims) {
  if (CaptureSession* s = active()) {
    const std::function<void()> f = call;
    s->draw(f, {DrawCallPart{f, prims}});
  } else {
    call();
  }
}

}  // namespace

}  // namespace ropsim::glcapture

using namespace ropsim::glcapture;

// ------------------------------------------------------------------ draws

ROPSIM_EXPORT void glDrawArrays(GLenum mode, GLint first, GLsizei count) {
  draw([=] { real_gl().DrawArrays(mode, first, count); }, primitives_per_instance(mode, count));
}

ROPSIM_EXPORT void glDrawElements(GLenum mode, GLsizei count, GLenum type, const void* indices) {
  draw([=] { real_gl().DrawElements(mode, count, type, indices); }, primitives_per_instance(mode, count));
}

ROPSIM_EXPORT void glDrawArraysInstanced(GLenum mode, GLint first, GLsizei count, GLsizei n) {
  draw([=] { real_gl().DrawArraysInstanced(mode, first, count, n); }, primitives_per_instance(mode, count));
}

ROPSIM_EXPORT void glDrawElementsInstanced(GLenum mode, GLsizei count, GLenum type, const void* indices, GLsizei n) {
  draw([=] { real_gl().DrawElementsInstanced(mode, count, type, indices, n); }, primitives_per_instance(mode, count));
}

ROPSIM_EXPORT void glDrawElementsBaseVertex(GLenum mode, GLsizei count, GLenum type, const void* indices, GLint base) {
  draw([=] { real_gl().DrawElementsBaseVertex(mode, count, type, indices, base); },
       primitives_per_instance(mode, count));
}

ROPSIM_EXPORT void glDrawElementsInstancedBaseVertex(GLenum mode, GLsizei count, GLenum type, const void* indices,
                                                     GLsizei n, GLint base) {
  draw([=] { real_gl().DrawElementsInstancedBaseVertex(mode, count, type, indices, n, base); },
       primitives_per_instance(mode, count));
}

ROPSIM_EXPORT void glDrawRangeElements(GLenum mode, GLuint start, GLuint end, GLsizei count, GLenum type,
                                       const void* indices) {
  draw([=] { real_gl().DrawRangeElements(mode, start, end, count, type, indices); },
       primitives_per_instance(mode, count));
}

ROPSIM_EXPORT void glDrawRangeElementsBaseVertex(GLenum mode, GLuint start, GLuint end, GLsizei count, GLenum type,
                                                 const void* indices, GLint base) {
  draw([=] { real_gl().DrawRangeElementsBaseVertex(mode, start, end, count, type, indices, base); },
       primitives_per_instance(mode, count));
}

ROPSIM_EXPORT void glDrawArraysInstancedBaseInstance(GLenum mode, GLint first, GLsizei count, GLsizei n,
                                                     GLuint base_instance) {
  draw([=] { real_gl().DrawArraysInstancedBaseInstance(mode, first, count, n, base_instance); },
       primitives_per_instance(mode, count));
}

ROPSIM_EXPORT void glDrawElementsInstancedBaseInstance(GLenum mode, GLsizei count, GLenum type, const void* indices,
                                                       GLsizei n, GLuint base_instance) {
  draw([=] { real_gl().DrawElementsInstancedBaseInstance(mode, count, type, indices, n, base_instance); },
       primitives_per_instance(mode, count));
}

ROPSIM_EXPORT void glDrawElementsInstancedBaseVertexBaseInstance(GLenum mode, GLsizei count, GLenum type,
                                                                 const void* indices, GLsizei n, GLint base,
                                                                 GLuint base_instance) {
  draw(
      [=] {
        real_gl().DrawElementsInstancedBaseVertexBaseInstance(mode, count, type, indices, n, base, base_instance);
      },
      primitives_per_instance(mode, count));
}

// Indirect draws: the counts are in a buffer; primitive ids come from the records.
ROPSIM_EXPORT void glDrawArraysIndirect(GLenum mode, const void* indirect) {
  draw([=] { real_gl().DrawArraysIndirect(mode, indirect); }, 0);
}

ROPSIM_EXPORT void glDrawElementsIndirect(GLenum mode, GLenum type, const void* indirect) {
  draw([=] { real_gl().DrawElementsIndirect(mode, type, indirect); }, 0);
}

// The multi-draws: one trace draw, a part per sub-draw (gl_PrimitiveID
// restarts in each).
ROPSIM_EXPORT void glMultiDrawArrays(GLenum mode, const GLint* first, const GLsizei* count, GLsizei n) {
  auto call = [=] { real_gl().MultiDrawArrays(mode, first, count, n); };
  CaptureSession* s = active();
  if (!s) return call();
  std::vector<DrawCallPart> parts;
  for (GLsizei i = 0; i < n; ++i) {
    const GLint f = first[i];
    const GLsizei c = count[i];
    parts.push_back({[=] { real_gl().DrawArrays(mode, f, c); }, primitives_per_instance(mode, c)});
  }
  s->draw(call, parts);
}

ROPSIM_EXPORT void glMultiDrawElements(GLenum mode, const GLsizei* count, GLenum type, const void* const* indices,
                                       GLsizei n) {
  auto call = [=] { real_gl().MultiDrawElements(mode, count, type, indices, n); };
  CaptureSession* s = active();
  if (!s) return call();
  std::vector<DrawCallPart> parts;
  for (GLsizei i = 0; i < n; ++i) {
    const GLsizei c = count[i];
    const void* ix = indices[i];
    parts.push_back({[=] { real_gl().DrawElements(mode, c, type, ix); }, primitives_per_instance(mode, c)});
  }
  s->draw(call, parts);
}

ROPSIM_EXPORT void glMultiDrawElementsBaseVertex(GLenum mode, const GLsizei* count, GLenum type,
                                                 const void* const* indices, GLsizei n, const GLint* base) {
  auto call = [=] { real_gl().MultiDrawElementsBaseVertex(mode, count, type, indices, n, base); };
  CaptureSession* s = active();
  if (!s) return call();
  std::vector<DrawCallPart> parts;
  for (GLsizei i = 0; i < n; ++i) {
    const GLsizei c = count[i];
    const void* ix = indices[i];
    const GLint b = base[i];
    parts.push_back(
        {[=] { real_gl().DrawElementsBaseVertex(mode, c, type, ix, b); }, primitives_per_instance(mode, c)});
  }
  s->draw(call, parts);
}

ROPSIM_EXPORT void glMultiDrawArraysIndirect(GLenum mode, const void* indirect, GLsizei n, GLsizei stride) {
  const auto* base = static_cast<const char*>(indirect);
  auto call = [=] { real_gl().MultiDrawArraysIndirect(mode, indirect, n, stride); };
  CaptureSession* s = active();
  if (!s) return call();
  std::vector<DrawCallPart> parts;
  const GLsizei step = stride ? stride : GLsizei(4 * sizeof(GLuint));
  for (GLsizei i = 0; i < n; ++i) {
    const void* cmd = base + size_t(i) * size_t(step);
    parts.push_back({[=] { real_gl().DrawArraysIndirect(mode, cmd); }, 0});
  }
  s->draw(call, parts);
}

ROPSIM_EXPORT void glMultiDrawElementsIndirect(GLenum mode, GLenum type, const void* indirect, GLsizei n,
                                               GLsizei stride) {
  const auto* base = static_cast<const char*>(indirect);
  auto call = [=] { real_gl().MultiDrawElementsIndirect(mode, type, indirect, n, stride); };
  CaptureSession* s = active();
  if (!s) return call();
  std::vector<DrawCallPart> parts;
  const GLsizei step = stride ? stride : GLsizei(5 * sizeof(GLuint));
  for (GLsizei i = 0; i < n; ++i) {
    const void* cmd = base + size_t(i) * size_t(step);
    parts.push_back({[=] { real_gl().DrawElementsIndirect(mode, type, cmd); }, 0});
  }
  s->draw(call, parts);
}

// Immediate mode: drawn as usual, listed unsupported (the vertices are not
// recorded, so the draw cannot be re-executed).
ROPSIM_EXPORT void glBegin(GLenum mode) { real_gl().Begin(mode); }

ROPSIM_EXPORT void glEnd() {
  real_gl().End();
  if (CaptureSession* s = active()) s->unsupported_draw("immediate mode (glBegin/glEnd) is not re-executed");
}

// Display lists: drawn as usual, listed unsupported (their contents are not
// recorded).
ROPSIM_EXPORT void glCallList(GLuint list) {
  real_gl().CallList(list);
  if (CaptureSession* s = active()) s->unsupported_draw("a display list (glCallList) is not re-executed");
}

ROPSIM_EXPORT void glCallLists(GLsizei n, GLenum type, const void* lists) {
  real_gl().CallLists(n, type, lists);
  if (CaptureSession* s = active()) s->unsupported_draw("display lists (glCallLists) are not re-executed");
}

// ------------------------------------------------------------------ state

ROPSIM_EXPORT void glClear(GLbitfield mask) {
  if (CaptureSession* s = active()) s->clear(mask);
  real_gl().Clear(mask);
}

ROPSIM_EXPORT void glUseProgram(GLuint program) { real_gl().UseProgram(program); }

namespace {
bool app_conditional_render = false;
}  // namespace

bool ropsim::glcapture::application_conditional_render() { return app_conditional_render; }

ROPSIM_EXPORT void glBeginConditionalRender(GLuint id, GLenum mode) {
  real_gl().BeginConditionalRender(id, mode);
  app_conditional_render = true;
}

ROPSIM_EXPORT void glEndConditionalRender() {
  real_gl().EndConditionalRender();
  app_conditional_render = false;
}

ROPSIM_EXPORT void glLinkProgram(GLuint program) {
  real_gl().LinkProgram(program);
  if (CaptureSession* s = session()) s->linked(program);
}

ROPSIM_EXPORT void glDeleteProgram(GLuint program) {
  if (CaptureSession* s = session()) s->deleting_program(program);
  real_gl().DeleteProgram(program);
}

ROPSIM_EXPORT void glBindFramebuffer(GLenum target, GLuint framebuffer) {
  real_gl().BindFramebuffer(target, framebuffer);
}

ROPSIM_EXPORT void glObjectLabel(GLenum identifier, GLuint name, GLsizei length, const GLchar* label) {
  real_gl().ObjectLabel(identifier, name, length, label);
}

// ------------------------------------------------------------------ window system

ROPSIM_EXPORT void glXSwapBuffers(Display* dpy, GLXDrawable drawable) {
  if (CaptureSession* s = session()) s->swap();
  real_gl().glXSwapBuffers(dpy, drawable);
}

ROPSIM_EXPORT EGLBoolean eglSwapBuffers(EGLDisplay dpy, EGLSurface surface) {
  if (CaptureSession* s = session()) s->swap();
  return real_gl().eglSwapBuffers(dpy, surface);
}

ROPSIM_EXPORT Bool glXMakeCurrent(Display* dpy, GLXDrawable drawable, GLXContext ctx) {
  const Bool ok = real_gl().glXMakeCurrent(dpy, drawable, ctx);
  if (CaptureSession* s = session(); s && ok && ctx) s->made_current(ctx);
  return ok;
}

ROPSIM_EXPORT Bool glXMakeContextCurrent(Display* dpy, GLXDrawable draw, GLXDrawable read, GLXContext ctx) {
  const Bool ok = real_gl().glXMakeContextCurrent(dpy, draw, read, ctx);
  if (CaptureSession* s = session(); s && ok && ctx) s->made_current(ctx);
  return ok;
}

ROPSIM_EXPORT EGLBoolean eglMakeCurrent(EGLDisplay dpy, EGLSurface draw, EGLSurface read, EGLContext ctx) {
  const EGLBoolean ok = real_gl().eglMakeCurrent(dpy, draw, read, ctx);
  if (CaptureSession* s = session(); s && ok && ctx != EGL_NO_CONTEXT) s->made_current(ctx);
  return ok;
}

ROPSIM_EXPORT void glXDestroyContext(Display* dpy, GLXContext ctx) {
  if (CaptureSession* s = session()) s->destroying_context(ctx);
  real_gl().glXDestroyContext(dpy, ctx);
}

ROPSIM_EXPORT EGLBoolean eglDestroyContext(EGLDisplay dpy, EGLContext ctx) {
  if (CaptureSession* s = session()) s->destroying_context(ctx);
  return real_gl().eglDestroyContext(dpy, ctx);
}

// ------------------------------------------------------------------ look-ups

namespace {

struct Wrapper {
  const char* name;
  void* function;
};

#define ROPSIM_WRAPPER(name) \
  { #name, reinterpret_cast < void*>(&name) }
const Wrapper kWrappers[] = {
    ROPSIM_WRAPPER(glDrawArrays),
    ROPSIM_WRAPPER(glDrawElements),
    ROPSIM_WRAPPER(glDrawArraysInstanced),
    {"glDrawArraysInstancedARB", reinterpret_cast<void*>(&glDrawArraysInstanced)},
    {"glDrawArraysInstancedEXT", reinterpret_cast<void*>(&glDrawArraysInstanced)},
    ROPSIM_WRAPPER(glDrawElementsInstanced),
    {"glDrawElementsInstancedARB", reinterpret_cast<void*>(&glDrawElementsInstanced)},
    {"glDrawElementsInstancedEXT", reinterpret_cast<void*>(&glDrawElementsInstanced)},
    ROPSIM_WRAPPER(glDrawElementsBaseVertex),
    ROPSIM_WRAPPER(glDrawElementsInstancedBaseVertex),
    ROPSIM_WRAPPER(glDrawRangeElements),
    {"glDrawRangeElementsEXT", reinterpret_cast<void*>(&glDrawRangeElements)},
    ROPSIM_WRAPPER(glDrawRangeElementsBaseVertex),
    ROPSIM_WRAPPER(glDrawArraysInstancedBaseInstance),
    ROPSIM_WRAPPER(glDrawElementsInstancedBaseInstance),
    ROPSIM_WRAPPER(glDrawElementsInstancedBaseVertexBaseInstance),
    ROPSIM_WRAPPER(glDrawArraysIndirect),
    ROPSIM_WRAPPER(glDrawElementsIndirect),
    ROPSIM_WRAPPER(glMultiDrawArrays),
    {"glMultiDrawArraysEXT", reinterpret_cast<void*>(&glMultiDrawArrays)},
    ROPSIM_WRAPPER(glMultiDrawElements),
    {"glMultiDrawElementsEXT", reinterpret_cast<void*>(&glMultiDrawElements)},
    ROPSIM_WRAPPER(glMultiDrawElementsBaseVertex),
    ROPSIM_WRAPPER(glMultiDrawArraysIndirect),
    ROPSIM_WRAPPER(glMultiDrawElementsIndirect),
    ROPSIM_WRAPPER(glBegin),
    ROPSIM_WRAPPER(glCallList),
    ROPSIM_WRAPPER(glCallLists),
    ROPSIM_WRAPPER(glEnd),
    ROPSIM_WRAPPER(glClear),
    ROPSIM_WRAPPER(glUseProgram),
    ROPSIM_WRAPPER(glBeginConditionalRender),
    {"glBeginConditionalRenderNV", reinterpret_cast<void*>(&glBeginConditionalRender)},
    ROPSIM_WRAPPER(glEndConditionalRender),
    {"glEndConditionalRenderNV", reinterpret_cast<void*>(&glEndConditionalRender)},
    ROPSIM_WRAPPER(glLinkProgram),
    ROPSIM_WRAPPER(glDeleteProgram),
    ROPSIM_WRAPPER(glBindFramebuffer),
    ROPSIM_WRAPPER(glObjectLabel),
    ROPSIM_WRAPPER(glXSwapBuffers),
    ROPSIM_WRAPPER(eglSwapBuffers),
    ROPSIM_WRAPPER(glXMakeCurrent),
    ROPSIM_WRAPPER(glXMakeContextCurrent),
    ROPSIM_WRAPPER(eglMakeCurrent),
    ROPSIM_WRAPPER(glXDestroyContext),
    ROPSIM_WRAPPER(eglDestroyContext),
};
#undef ROPSIM_WRAPPER

void* wrapper(const char* name) {
  if (!name || !session()) return nullptr;
  for (const Wrapper& w : kWrappers)
    if (std::strcmp(w.name, name) == 0) return w.function;
  return nullptr;
}

}  // namespace

ROPSIM_EXPORT __GLXextFuncPtr glXGetProcAddressARB(const GLubyte* name) {
  if (void* w = wrapper(reinterpret_cast<const char*>(name))) return reinterpret_cast<__GLXextFuncPtr>(w);
  return real_gl().glXGetProcAddressARB(name);
}

ROPSIM_EXPORT __GLXextFuncPtr glXGetProcAddress(const GLubyte* name) { return glXGetProcAddressARB(name); }

ROPSIM_EXPORT __eglMustCastToProperFunctionPointerType eglGetProcAddress(const char* name) {
  if (void* w = wrapper(name)) return reinterpret_cast<__eglMustCastToProperFunctionPointerType>(w);
  return real_gl().eglGetProcAddress(name);
}

ROPSIM_EXPORT void* dlopen(const char* filename, int flags) {
  if (filename && session() && is_gl_library(filename) && *own_path()) return real_dlopen()(own_path(), flags);
  return real_dlopen()(filename, flags);
}
