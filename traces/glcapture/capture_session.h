// The capture of one frame of an OpenGL application (docs/capture.md
// "Capturing a GL frame"): the session the preloaded library drives from the
// application's calls. It counts frames at the buffer swaps; during frame N
// it re-executes every draw into the target with the instrumented program,
// one pass per sample position, and at the end of frame N writes the trace,
// list.json, frame.rgba and status.json into ROPSIM_GL_CONTROL's folder and
// ends the process. The interface with `ropsim capture gl` is GLCAPTURE.md's.
#pragma once
#include <GL/gl.h>

#include <cstdint>
#include <functional>
#include <vector>

namespace ropsim::glcapture {

/// One part of a draw call (a glMultiDraw* call has one per sub-draw): the
/// call that draws it alone, and its primitives per instance when the call
/// says (0: unknown).
struct DrawCallPart {
  std::function<void()> replay;
  uint32_t prims_per_instance = 0;
};

/// Primitives one instance of `count` vertices in `mode` makes.
uint32_t primitives_per_instance(GLenum mode, GLsizei count);

class CaptureSession;
/// The session, or nullptr when ROPSIM_GL_CONTROL is not set (the library
/// then only forwards every call).
CaptureSession* session();

class CaptureSession {
 public:
  virtual ~CaptureSession() = default;
  /// During frame N (the draws are captured).
  virtual bool capturing() const = 0;
  /// A draw: `app` executes the application's call; parts re-execute it.
  virtual void draw(const std::function<void()>& app, const std::vector<DrawCallPart>& parts) = 0;
  /// A draw the capture cannot re-execute (immediate mode); drawn, listed unsupported.
  virtual void unsupported_draw(const char* reason) = 0;
  virtual void clear(GLbitfield mask) = 0;
  /// Before the real swap: the end of a frame.
  virtual void swap() = 0;
  virtual void linked(GLuint program) = 0;
  virtual void deleting_program(GLuint program) = 0;
  virtual void made_current(const void* context) = 0;
  virtual void destroying_context(const void* context) = 0;
};

}  // namespace ropsim::glcapture
