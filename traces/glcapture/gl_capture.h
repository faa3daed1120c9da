// One frame of a real OpenGL application into a trace (docs/capture.md
// "Capturing a frame of an OpenGL application"): the application run live
// under a private Xvfb with Mesa's llvmpipe, or an apitrace trace replayed
// by glretrace, with the capture library preloaded. `ropsim capture gl` and a
// study's application inputs both run it.
#pragma once
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "util/child_process.h"

namespace ropsim {

struct GlCaptureRequest {
  int64_t frame = 0;  ///< frames count from 0: the work after the frame-th buffer swap
  int spp = 1;
  unsigned width = 1280, height = 1024;  ///< the virtual X screen, pixels
  std::string target = "presented";      ///< presented or fbo:N
  double timeout = 120;                  ///< seconds to the end of the frame
  std::string out;                       ///< the trace (written atomically); "" with list
  std::string apitrace;                  ///< replay this apitrace trace, or
  std::vector<std::string> app;          ///< run this application
  std::string keep_control;              ///< keep the library's files here ("" = a private folder, removed)
  bool list = false;                     ///< write no trace: only the frame's framebuffers and draws
  bool count_samples = false;            ///< occlusion-query counts per draw (list.json samples_passed)
  bool reference_msaa = false;           ///< also frame-msaa4.rgba (needs keep_control)
  std::string what;                      ///< names the application in messages ("" = app[0], or the apitrace file)
  std::string package;                   ///< the Debian package of app[0], named when it is not installed
};

struct GlCaptureResult {
  nlohmann::json status;  ///< the library's status.json
  nlohmann::json list;    ///< its list.json: the frame's framebuffers and draws
  uint64_t bytes = 0;     ///< the trace's size (0 with list)
  std::string what;       ///< names the application (or the trace) in messages
};

/// Runs the capture; throws UserError (one line naming the application or
/// the trace) when it cannot. signals (may be null): a caught signal stops
/// the children, removes the private folder and raises the signal again.
GlCaptureResult run_gl_capture(const GlCaptureRequest& r, StopSignals* signals = nullptr);

/// "fbo:N" -> "fbo N" (list.json's framebuffer names); "presented" stays.
std::string gl_target_name(const std::string& target);

/// j[key] as T, or fallback when it is absent, null or of another type.
template <class T>
T json_field(const nlohmann::json& j, const char* key, T fallback) {
  const auto it = j.find(key);
  if (it == j.end() || it->is_null()) return fallback;
  try {
    return it->get<T>();
  } catch (const nlohmann::json::exception&) {
    return fallback;
  }
}

}  // namespace ropsim
