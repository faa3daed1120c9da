// The frame of the GL test programs (tests/gl/*.cpp; tests/test_capture_gl.cpp
// captures them with `ropsim capture gl`): a GLX window of a given size on
// $DISPLAY, a compatibility context (Mesa: GL 4.5), a shader helper, and the
// loop that draws the same frame a few times, swapping after each.
//
// Common arguments: --size WxH (default 64x64), --frames N (default 3),
// --dump FILE (the last frame's pixels, read back before its swap, as a
// binary PPM, top row first: to look at what a program draws).
// Any failure prints one line "PROGRAM: ..." on stderr and exits 1.
#pragma once
#define GL_GLEXT_PROTOTYPES 1
#include <GL/gl.h>
#include <GL/glext.h>
#include <GL/glx.h>
#include <X11/Xlib.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace gltest {

struct App {
  const char* name = "gl_test";
  Display* dpy = nullptr;
  Window win = 0;
  GLXContext ctx = nullptr;
  int width = 64, height = 64, frames = 3;
  const char* dump = nullptr;
};

[[noreturn]] inline void die(const App& a, const std::string& what) {
  std::fprintf(stderr, "%s: %s\n", a.name, what.c_str());
  std::exit(1);
}

/// Parses --size and --frames (other arguments are left to the program:
/// arg(i) returns them), opens the window and makes the context current.
inline App open(int argc, char** argv, const char* name) {
  App a;
  a.name = name;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--size") && i + 1 < argc) {
      if (std::sscanf(argv[++i], "%dx%d", &a.width, &a.height) != 2 || a.width < 1 || a.height < 1)
        die(a, std::string("--size ") + argv[i] + ": not WxH");
    } else if (!std::strcmp(argv[i], "--frames") && i + 1 < argc) {
      a.frames = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--dump") && i + 1 < argc) {
      a.dump = argv[++i];
    }
  }
  a.dpy = XOpenDisplay(nullptr);
  if (!a.dpy) die(a, "cannot open the X display (is DISPLAY set?)");
  const int attrs[] = {GLX_X_RENDERABLE,
                       True,
                       GLX_DRAWABLE_TYPE,
                       GLX_WINDOW_BIT,
                       GLX_RENDER_TYPE,
                       GLX_RGBA_BIT,
                       GLX_RED_SIZE,
                       8,
                       GLX_GREEN_SIZE,
                       8,
                       GLX_BLUE_SIZE,
                       8,
                       GLX_ALPHA_SIZE,
                       8,
                       GLX_DEPTH_SIZE,
                       24,
                       GLX_DOUBLEBUFFER,
                       True,
                       GLX_SAMPLE_BUFFERS,
                       0,
                       None};
  int n = 0;
  GLXFBConfig* cfgs = glXChooseFBConfig(a.dpy, DefaultScreen(a.dpy), attrs, &n);
  if (!cfgs || n < 1) die(a, "no RGBA8 double-buffered GLX framebuffer configuration");
  XVisualInfo* vi = glXGetVisualFromFBConfig(a.dpy, cfgs[0]);
  XSetWindowAttributes swa{};
  swa.colormap = XCreateColormap(a.dpy, RootWindow(a.dpy, vi->screen), vi->visual, AllocNone);
  swa.event_mask = StructureNotifyMask;
  a.win = XCreateWindow(a.dpy, RootWindow(a.dpy, vi->screen), 0, 0, unsigned(a.width), unsigned(a.height), 0, vi->depth,
                        InputOutput, vi->visual, CWColormap | CWEventMask, &swa);
  XStoreName(a.dpy, a.win, name);
  XMapWindow(a.dpy, a.win);
  for (XEvent e;;) {  // mapped: the back buffer has the window's size
    XNextEvent(a.dpy, &e);
    if (e.type == MapNotify) break;
  }
  a.ctx = glXCreateNewContext(a.dpy, cfgs[0], GLX_RGBA_TYPE, nullptr, True);
  if (!a.ctx || !glXMakeContextCurrent(a.dpy, a.win, a.win, a.ctx)) die(a, "cannot make a GLX context current");
  XFree(vi);
  XFree(cfgs);
  glViewport(0, 0, a.width, a.height);
  return a;
}

/// The value after `flag` in argv, or fallback.
inline const char* arg(int argc, char** argv, const char* flag, const char* fallback) {
  for (int i = 1; i + 1 < argc; ++i)
    if (!std::strcmp(argv[i], flag)) return argv[i + 1];
  return fallback;
}

inline GLuint shader(const App& a, GLenum kind, const char* src) {
  const GLuint s = glCreateShader(kind);
  glShaderSource(s, 1, &src, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetShaderInfoLog(s, sizeof log, nullptr, log);
    die(a, std::string("shader does not compile: ") + log);
  }
  return s;
}

/// A linked program from a vertex and a fragment shader; label (may be null)
/// becomes its GL debug label (glObjectLabel).
inline GLuint program(const App& a, const char* vs, const char* fs, const char* label = nullptr) {
  const GLuint p = glCreateProgram();
  glAttachShader(p, shader(a, GL_VERTEX_SHADER, vs));
  glAttachShader(p, shader(a, GL_FRAGMENT_SHADER, fs));
  glLinkProgram(p);
  GLint ok = 0;
  glGetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetProgramInfoLog(p, sizeof log, nullptr, log);
    die(a, std::string("program does not link: ") + log);
  }
  if (label) glObjectLabel(GL_PROGRAM, p, -1, label);
  return p;
}

/// Draws the frame a.frames times (draw(frame_index)), swapping after each,
/// then closes the window and returns the exit status 0.
template <class Draw>
int run(App& a, Draw draw) {
  for (int f = 0; f < a.frames; ++f) {
    draw(f);
    if (a.dump && f + 1 == a.frames) {
      std::string rgb(size_t(a.width) * size_t(a.height) * 3, '\0');
      glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
      glReadBuffer(GL_BACK);
      glPixelStorei(GL_PACK_ALIGNMENT, 1);
      glReadPixels(0, 0, a.width, a.height, GL_RGB, GL_UNSIGNED_BYTE, &rgb[0]);
      FILE* out = std::fopen(a.dump, "wb");
      if (!out) die(a, std::string(a.dump) + ": cannot write");
      std::fprintf(out, "P6\n%d %d\n255\n", a.width, a.height);
      for (int y = a.height - 1; y >= 0; --y)
        std::fwrite(&rgb[size_t(y) * size_t(a.width) * 3], 1, size_t(a.width) * 3, out);
      std::fclose(out);
    }
    glXSwapBuffers(a.dpy, a.win);
  }
  glXMakeContextCurrent(a.dpy, None, None, nullptr);
  glXDestroyContext(a.dpy, a.ctx);
  XDestroyWindow(a.dpy, a.win);
  XCloseDisplay(a.dpy);
  return 0;
}

/// A vertex buffer holding n floats, bound to attribute `index` with
/// `components` floats per vertex (a vertex array object must be bound).
inline GLuint attribute(GLuint index, int components, const float* data, size_t n) {
  GLuint b = 0;
  glGenBuffers(1, &b);
  glBindBuffer(GL_ARRAY_BUFFER, b);
  glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(n * sizeof(float)), data, GL_STATIC_DRAW);
  glVertexAttribPointer(index, components, GL_FLOAT, GL_FALSE, 0, nullptr);
  glEnableVertexAttribArray(index);
  return b;
}

}  // namespace gltest
