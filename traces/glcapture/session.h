// The capture session's internals (docs/capture.md "The GL capture
// library"): the Session class that capture_session.cpp (configuration,
// frames, draws, status), session_passes.cpp (the capture objects and a
// draw's passes) and session_output.cpp (the frame's end: the trace and the
// files) implement. Private to the capture library.
#pragma once
#include <GL/gl.h>

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "traces/format/draw_state.h"
#include "traces/glcapture/capture_session.h"
#include "traces/glcapture/fragment_order.h"
#include "traces/glcapture/glsl_rewrite.h"
#include "traces/glcapture/instrumented_program.h"
#include "traces/glcapture/session_state.h"

namespace ropsim::glcapture {

using nlohmann::json;

struct DrawRecord {
  uint32_t index = 0;     ///< in the frame (every framebuffer's draws): list.json's index
  uint32_t trace_id = 0;  ///< among the target's draws: the trace's draw_id
  std::string framebuffer;
  GLuint program = 0;
  std::string name;
  bool target = false;
  DrawState state;
  uint64_t fragments = 0, covered_samples = 0;
  bool counted = false;
  uint64_t samples_passed = 0;
};

struct Unsupported {
  uint32_t draw;
  std::string name, reason;
};

class Session final : public CaptureSession {
 public:
  Session();
  bool capturing() const override { return frames_seen_ == frame_ && !finished_ && config_error_.empty(); }
  void draw(const std::function<void()>& app, const std::vector<DrawCallPart>& parts) override;
  void unsupported_draw(const char* reason) override;
  void clear(GLbitfield mask) override;
  void swap() override;
  void linked(GLuint program) override;
  void deleting_program(GLuint program) override;
  void made_current(const void* context) override {
    contexts_.insert(context);
    used_gl_ = true;
    if (!config_error_.empty()) fail(config_error_);
  }
  void destroying_context(const void* context) override;
  void at_exit();

 private:
  [[noreturn]] void fail(const std::string& error);
  void config_failure(const std::string& error) { config_error_ = error; }
  /// Reads the ROPSIM_GL_* variables.
  void configure();
  bool write_status(bool ok, const std::string& error);
  json list_json() const;
  FramebufferInfo& framebuffer(GLint fbo);
  bool is_target(GLint fbo) const { return target_presented_ ? fbo == 0 : GLuint(fbo) == target_fbo_; }
  void use_target(const FramebufferInfo& fb);
  std::string program_name(GLuint program) const;
  ProgramSet& instrumented(GLuint program);
  /// The fixed-function state's program, instrumented; or the reason it is not captured.
  ProgramSet* fixed_function(std::string& unsupported);
  /// Builds the set's shading and coverage twins (once).
  void build_split(GLuint program, ProgramSet& set);
  void capture_draw(GLuint program, const ProgramSet& set, const std::vector<DrawCallPart>& parts, DrawRecord& d);
  /// The capture framebuffer's stencil buffer (made at the first draw that needs it).
  void attach_capture_stencil();
  /// Sample pass `s` above 1 spp: the coverage pass, then the shading pass
  /// (shifted by `off` in clip space, `pixel_off` in pixels); with `query`,
  /// the shading pass only when the coverage pass keeps a fragment.
  void split_pass(const ProgramSet& set, int s, std::array<float, 2> off, std::array<float, 2> pixel_off,
                  const std::vector<DrawCallPart>& parts, bool query);
  /// The wrapper's alpha test for this draw (on: a GLSL program with GL_ALPHA_TEST on).
  void set_alpha_test(const Instrumented& ins, bool on);
  void reference_draw(GLuint program, const Instrumented& ins, const std::vector<DrawCallPart>& parts);
  void render_passes(const std::vector<DrawCallPart>& parts);
  /// Node buffers for `nodes` fragments (keys, state, colour; the depths at the next pass).
  void reserve_nodes(uint64_t nodes);
  /// Binds the node buffers (the depths of sample `sample`'s pass).
  void bind_nodes(int sample);
  void finish_frame();
  std::vector<uint8_t> read_target(GLint fbo, bool presented, int w, int h, bool upside_down = false) const;

  // Configuration (the environment).
  std::string dir_, out_;
  long frame_ = 0;
  int spp_ = 1;
  bool list_only_ = false, count_samples_ = false, reference_msaa_ = false;
  /// ROPSIM_GL_RENDER_PASSES=1: the passes with the application's programs, no records (the benchmark's baseline).
  bool render_passes_ = false;
  /// ROPSIM_GL_TIMES: a file the phases' seconds are written to at the frame's end.
  std::string times_;
  bool target_presented_ = true;
  GLuint target_fbo_ = 0;
  std::string target_text_ = "presented";

  /// A bad ROPSIM_GL_* value: reported when the process first makes a context
  /// current (a shell or server the preload also reaches is left alone).
  std::string config_error_;
  long frames_seen_ = 0;
  bool finished_ = false;
  bool status_written_ = false;
  /// A context was made current in this process: only then does its exit
  /// report (a shell or server the preload also reaches says nothing).
  bool used_gl_ = false;
  std::set<const void*> contexts_;
  std::map<GLuint, std::vector<ShaderSource>> sources_;
  std::map<GLuint, ProgramSet> instrumented_;
  std::map<std::string, ProgramSet> fixed_function_;  ///< by the generated sources

  // Frame N.
  std::vector<FramebufferInfo> framebuffers_;
  std::vector<DrawRecord> draws_;
  std::vector<Unsupported> unsupported_;
  /// The trace, its records framed and compressed draw by draw and its
  /// header written at the frame's end (made at the first draw into the
  /// target; none for a list).
  std::unique_ptr<TraceWriter> trace_;
  BuildScratch scratch_;       ///< build_records()'s arrays, kept from draw to draw
  uint32_t target_draws_ = 0;  ///< draws into the target so far (the next trace draw id)
  bool target_known_ = false;
  bool compatibility_ = false;  ///< the context has the compatibility profile
  FramebufferInfo target_;
  bool color_cleared_ = false, depth_cleared_ = false;
  std::array<float, 3> clear_color_{0, 0, 0};
  float clear_depth_ = 1.0f;
  GLuint capture_fbo_ = 0, query_ = 0;
  GLuint kept_query_ = 0;         ///< whether a coverage pass keeps a fragment (GL_ANY_SAMPLES_PASSED)
  bool capture_stencil_ = false;  ///< the capture framebuffer has its stencil buffer
  /// The coverage passes' buffer textures over the list heads and the keys,
  /// on texture units fetch_unit_ and fetch_unit_ + 1 (the last two).
  std::array<GLuint, 2> fetch_textures_{};
  GLint fetch_unit_ = 0;
  /// The node buffers (glsl_rewrite.h kCaptureBindings): list heads, keys,
  /// state, colour, and the depths (a range of node_capacity_ words a sample).
  std::array<GLuint, kCaptureBindings> node_buffers_{};
  /// The driver takes the library's memory as a buffer's store
  /// (GL_AMD_pinned_memory, as llvmpipe does): the node buffers' stores are
  /// then fresh mappings of the library's own, which the driver does not
  /// clear, so that only the pages the passes write are ever touched, and
  /// the depths, zero there (kNoDepth), need no clearing either.
  bool pinned_ = false;
  std::array<LargeArray<uint8_t>, kCaptureBindings> node_memory_;  ///< the pinned stores
  /// A new store of `bytes` for node buffer b (pinned where the driver
  /// takes it). Returns whether it reads as zero (fresh pinned pages).
  bool node_store(int b, uint64_t bytes);
  /// A node's bytes in node buffer b (1..3): keys and colour 16, state 4.
  static uint64_t node_bytes(int b) { return b == 2 ? 4 : 16; }
  GLint binding_ = 0;
  uint64_t node_capacity_ = 0, max_nodes_ = 0, depth_capacity_ = 0;
  /// Lists a pixel: a fragment's is (its primitive + instance + part) mod lists_ (glsl_rewrite.h).
  uint64_t lists_ = 1;
  /// The list heads' buffer: the header words and lists_ heads a pixel.
  uint64_t heads_bytes() const {
    return kHeadsHeaderWords * 4 + uint64_t(target_.width) * uint64_t(target_.height) * lists_ * 4;
  }
  /// Nodes whose depths (in each sample's range) may not be kNoDepth: cleared before a draw's passes.
  uint64_t depth_dirty_ = 0;
  GLuint msaa_fbo_ = 0;
  GLuint render_fbo_ = 0;  ///< ROPSIM_GL_RENDER_PASSES's colour buffer
  /// Seconds in each phase of the frame's capture (ROPSIM_GL_TIMES).
  struct Times {
    double passes = 0, read_back = 0, build = 0, write = 0;
  } times_s_;
  /// The trace's layout: its header as build_records() and the writer know it before the frame's end.
  TraceHeader trace_layout() const;
  TraceWriter& trace();
};

double seconds_since(std::chrono::steady_clock::time_point t);
/// Writes `bytes` to PATH through a temporary name in the same folder.
bool write_file_atomic(const std::string& path, const void* bytes, size_t n, std::string& error);
bool write_json(const std::string& path, const json& j, std::string& error);

}  // namespace ropsim::glcapture
