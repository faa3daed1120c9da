#include "traces/glcapture/capture_session.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "traces/format/draw_state.h"
#include "traces/format/trace.h"
#include "traces/glcapture/fragment_order.h"
#include "traces/glcapture/gl_functions.h"
#include "traces/glcapture/glsl_rewrite.h"
#include "traces/glcapture/instrumented_program.h"
#include "traces/raster/sample_patterns.h"

#if ROPSIM_GLCAPTURE_FIXED_FUNCTION
#include "traces/glcapture/ff_program.h"
#endif

namespace ropsim::glcapture {

using nlohmann::json;

uint32_t primitives_per_instance(GLenum mode, GLsizei count) {
  const uint32_t n = count > 0 ? uint32_t(count) : 0;
  switch (mode) {
    case GL_POINTS:
      return n;
    case GL_LINES:
      return n / 2;
    case GL_LINE_STRIP:
      return n > 1 ? n - 1 : 0;
    case GL_LINE_LOOP:
      return n > 1 ? n : 0;
    case GL_TRIANGLES:
      return n / 3;
    case GL_TRIANGLE_STRIP:
    case GL_TRIANGLE_FAN:
      return n > 2 ? n - 2 : 0;
    case GL_QUADS:
      return n / 4;
    case GL_QUAD_STRIP:
      return n > 3 ? (n - 2) / 2 : 0;
    case GL_POLYGON:
      return n > 2 ? 1 : 0;
    case GL_LINES_ADJACENCY:
      return n / 4;
    case GL_LINE_STRIP_ADJACENCY:
      return n > 3 ? n - 3 : 0;
    case GL_TRIANGLES_ADJACENCY:
      return n / 6;
    case GL_TRIANGLE_STRIP_ADJACENCY:
      return n > 5 ? (n - 4) / 2 : 0;
    default:
      return 0;  // patches, or an error the application's call reports
  }
}

namespace {

// The library's own storage block bindings (the last kCaptureBindings): an
// application program that binds a block there cannot be captured.
GLint capture_binding() {
  GLint n = 0;
  real_gl().GetIntegerv(GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS, &n);
  return std::max(0, n - kCaptureBindings);
}

std::string env(const char* name) {
  const char* v = std::getenv(name);
  return v ? v : "";
}

bool parse_int(const std::string& s, long lo, long hi, long& out) {
  if (s.empty()) return false;
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(s.c_str(), &end, 10);
  if (errno || *end || v < lo || v > hi) return false;
  out = v;
  return true;
}

/// Writes `bytes` to PATH through a temporary name in the same folder.
bool write_file_atomic(const std::string& path, const void* bytes, size_t n, std::string& error) {
  const std::string tmp = path + ".tmp." + std::to_string(getpid());
  FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) {
    error = tmp + ": " + std::strerror(errno);
    return false;
  }
  const bool ok = std::fwrite(bytes, 1, n, f) == n;
  const int werr = errno;
  if (std::fclose(f) != 0 || !ok) {
    error = path + ": " + std::strerror(ok ? errno : werr);
    std::remove(tmp.c_str());
    return false;
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    error = path + ": " + std::strerror(errno);
    std::remove(tmp.c_str());
    return false;
  }
  return true;
}

bool write_json(const std::string& path, const json& j, std::string& error) {
  const std::string s = j.dump(2) + "\n";
  return write_file_atomic(path, s.data(), s.size(), error);
}

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

std::string blend_text(const DrawState& s) {
  if (!s.blend) return "off";
  return std::string(to_string(s.eq_rgb)) + "(" + to_string(s.src_rgb) + ", " + to_string(s.dst_rgb) + "), " +
         to_string(s.eq_alpha) + "(" + to_string(s.src_alpha) + ", " + to_string(s.dst_alpha) + ")";
}

std::string depth_text(const DrawState& s) {
  if (!s.depth_test) return "off";
  return std::string(to_string(s.depth_func)) + (s.depth_write ? ", write" : ", no write");
}

struct FramebufferInfo {
  std::string name;
  GLint fbo = 0;
  int width = 0, height = 0, samples = 0;
  TargetEncoding encoding = TargetEncoding::kUnorm8;
  bool has_depth = false, has_stencil = false, presented = false;
  int draws = 0;
};

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
  FramebufferInfo query_framebuffer(GLint fbo) const;
  bool is_target(GLint fbo) const { return target_presented_ ? fbo == 0 : GLuint(fbo) == target_fbo_; }
  void use_target(const FramebufferInfo& fb);
  DrawState read_state(uint32_t index, const FramebufferInfo& fb, std::string& unsupported) const;
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
  /// (shifted by `off` in clip space, `pixel_off` in pixels).
  void split_pass(const ProgramSet& set, int s, std::array<float, 2> off, std::array<float, 2> pixel_off,
                  const std::vector<DrawCallPart>& parts);
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
  std::vector<EncodedDraw> records_;  ///< a draw's trace records in API order, draw by draw
  uint32_t target_draws_ = 0;         ///< draws into the target so far (the next trace draw id)
  bool target_known_ = false;
  bool compatibility_ = false;  ///< the context has the compatibility profile
  FramebufferInfo target_;
  bool color_cleared_ = false, depth_cleared_ = false;
  std::array<float, 3> clear_color_{0, 0, 0};
  float clear_depth_ = 1.0f;
  GLuint capture_fbo_ = 0, query_ = 0;
  bool capture_stencil_ = false;  ///< the capture framebuffer has its stencil buffer
  /// The coverage passes' buffer textures over the list heads and the keys,
  /// on texture units fetch_unit_ and fetch_unit_ + 1 (the last two).
  std::array<GLuint, 2> fetch_textures_{};
  GLint fetch_unit_ = 0;
  /// The node buffers (glsl_rewrite.h kCaptureBindings): list heads, keys,
  /// state, colour, and the depths (a range of node_capacity_ words a sample).
  std::array<GLuint, kCaptureBindings> node_buffers_{};
  GLint binding_ = 0;
  uint64_t node_capacity_ = 0, max_nodes_ = 0, depth_capacity_ = 0;
  GLuint msaa_fbo_ = 0;
  GLuint render_fbo_ = 0;  ///< ROPSIM_GL_RENDER_PASSES's colour buffer
  /// Seconds in each phase of the frame's capture (ROPSIM_GL_TIMES).
  struct Times {
    double passes = 0, read_back = 0, build = 0, write = 0;
  } times_s_;
};

/// The trace's zstd level: 1, not the writer's default 3 (jellyfish's
/// 1920 x 1080 16-spp frame, 308 MB of records, compresses in 0.5 s instead
/// of 0.85 s, into a trace 2 % larger).
constexpr int kTraceZstdLevel = 1;
/// zstd's compression threads for the trace: a fixed count (not the
/// machine's), so that the trace's bytes are the same on every machine.
constexpr int kTraceZstdWorkers = 2;

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

Session::Session() {
  dir_ = env("ROPSIM_GL_CONTROL");
  configure();
}

void Session::configure() {
  long v = 0;
  const std::string frame = env("ROPSIM_GL_FRAME");
  if (!frame.empty()) {
    if (!parse_int(frame, 0, 1L << 30, v))
      return config_failure("ROPSIM_GL_FRAME: '" + frame + "' is not a frame number (0 or more)");
    frame_ = v;
  }
  const std::string spp = env("ROPSIM_GL_SPP");
  if (!spp.empty()) {
    if (!parse_int(spp, 1, 64, v) || (v & (v - 1)) != 0)
      return config_failure("ROPSIM_GL_SPP: '" + spp + "' is not 1, 2, 4, 8, 16, 32 or 64 samples per pixel");
    spp_ = int(v);
  }
  list_only_ = env("ROPSIM_GL_LIST_ONLY") == "1";
  count_samples_ = env("ROPSIM_GL_COUNT_SAMPLES") == "1";
  render_passes_ = env("ROPSIM_GL_RENDER_PASSES") == "1";
  if (render_passes_ && (!list_only_ || count_samples_))
    return config_failure("ROPSIM_GL_RENDER_PASSES=1 needs ROPSIM_GL_LIST_ONLY=1 and no ROPSIM_GL_COUNT_SAMPLES");
  times_ = env("ROPSIM_GL_TIMES");
  const std::string msaa = env("ROPSIM_GL_REFERENCE_MSAA");
  if (!msaa.empty() && msaa != "4")
    return config_failure("ROPSIM_GL_REFERENCE_MSAA: '" + msaa + "' is not 4 (the one reference)");
  reference_msaa_ = msaa == "4";
  out_ = env("ROPSIM_GL_OUT");
  if (out_.empty() && !list_only_) return config_failure("ROPSIM_GL_OUT is not set (the trace to write)");
  const std::string target = env("ROPSIM_GL_TARGET");
  if (!target.empty() && target != "presented") {
    if (target.compare(0, 4, "fbo:") != 0 || !parse_int(target.substr(4), 1, 0xFFFFFFFFL, v))
      return config_failure("ROPSIM_GL_TARGET: '" + target +
                            "' is neither presented nor fbo:N (a framebuffer object's name)");
    target_presented_ = false;
    target_fbo_ = GLuint(v);
    target_text_ = target;
  }
}

void Session::fail(const std::string& error) {
  write_status(false, error);
  if (!draws_.empty() || !framebuffers_.empty()) {
    std::string ignored;
    write_json(dir_ + "/list.json", list_json(), ignored);
  }
  std::fflush(stderr);
  _exit(1);
}

bool Session::write_status(bool ok, const std::string& error) {
  uint64_t fragments = 0;
  for (const DrawRecord& d : draws_) fragments += d.fragments;
  json unsupported = json::array();
  for (const Unsupported& u : unsupported_)
    unsupported.push_back({{"draw", u.draw}, {"name", u.name}, {"reason", u.reason}});
  uint32_t target_draws = 0;
  for (const DrawRecord& d : draws_) target_draws += d.target ? 1 : 0;
  const json j = {{"ok", ok},
                  {"error", error},
                  {"frames_seen", frames_seen_},
                  {"frame", frame_},
                  {"target", target_text_},
                  {"width", target_known_ ? target_.width : 0},
                  {"height", target_known_ ? target_.height : 0},
                  {"spp", spp_},
                  {"draws", target_draws},
                  {"fragments", fragments},
                  {"unsupported", unsupported}};
  std::string werr;
  status_written_ = write_json(dir_ + "/status.json", j, werr);
  if (!status_written_) std::fprintf(stderr, "ropsim: error: %s\n", werr.c_str());
  return status_written_;
}

json Session::list_json() const {
  json fbs = json::array(), draws = json::array();
  for (const FramebufferInfo& f : framebuffers_)
    fbs.push_back({{"name", f.name},
                   {"width", f.width},
                   {"height", f.height},
                   {"samples", f.samples},
                   {"encoding", encoding_name(f.encoding)},
                   {"draws", f.draws},
                   {"presented", f.presented}});
  for (const DrawRecord& d : draws_) {
    json j = {{"index", d.index},
              {"framebuffer", d.framebuffer},
              {"program", d.program},
              {"name", d.name},
              {"kind", to_string(draw_kind(d.state))},
              {"blend", blend_text(d.state)},
              {"depth", depth_text(d.state)},
              {"fragments", d.fragments},
              {"covered_samples", d.covered_samples},
              {"samples_passed", nullptr},
              {"captured", d.target},
              {"trace_draw", nullptr}};
    if (d.target) j["trace_draw"] = d.trace_id;
    if (d.counted) j["samples_passed"] = d.samples_passed;
    draws.push_back(j);
  }
  return {{"framebuffers", fbs}, {"draws", draws}};
}

FramebufferInfo Session::query_framebuffer(GLint fbo) const {
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

FramebufferInfo& Session::framebuffer(GLint fbo) {
  for (FramebufferInfo& f : framebuffers_)
    if (f.fbo == fbo) return f;
  framebuffers_.push_back(query_framebuffer(fbo));
  return framebuffers_.back();
}

void Session::use_target(const FramebufferInfo& fb) {
  if (target_known_) return;
  const GlFunctions& g = real_gl();
  if (fb.width <= 0 || fb.height <= 0 || uint32_t(fb.width) > kMaxScreenSide || uint32_t(fb.height) > kMaxScreenSide)
    fail("the target " + fb.name + " is " + std::to_string(fb.width) + "x" + std::to_string(fb.height) + ", not 1.." +
         std::to_string(kMaxScreenSide) + " pixels a side");
  target_ = fb;
  target_known_ = true;
  // A compatibility context (GL_ALPHA_TEST exists): before 3.2, or the profile says.
  const char* version = reinterpret_cast<const char*>(g.GetString(GL_VERSION));
  if (version && std::strncmp(version, "OpenGL ES", 9) == 0)
    fail(std::string("the context is OpenGL ES (") + version +
         "): the capture instruments desktop OpenGL (GLSL 4.50) only");
  const int major = version ? std::atoi(version) : 0;
  const int minor = version && std::strchr(version, '.') ? std::atoi(std::strchr(version, '.') + 1) : 0;
  compatibility_ = major < 3 || (major == 3 && minor < 2);
  if (!compatibility_) {
    GLint mask = 0;
    g.GetIntegerv(GL_CONTEXT_PROFILE_MASK, &mask);
    compatibility_ = (mask & GL_CONTEXT_COMPATIBILITY_PROFILE_BIT) != 0;
  }
  binding_ = capture_binding();
  GLint units = 0;
  g.GetIntegerv(GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS, &units);
  fetch_unit_ = std::max(0, units - 2);
  // The capture framebuffer: the target's size, no attachments (every write
  // but the storage buffer's goes nowhere; no depth or stencil buffer, so
  // no fragment is tested away).
  g.CreateFramebuffers(1, &capture_fbo_);
  g.NamedFramebufferParameteri(capture_fbo_, GL_FRAMEBUFFER_DEFAULT_WIDTH, fb.width);
  g.NamedFramebufferParameteri(capture_fbo_, GL_FRAMEBUFFER_DEFAULT_HEIGHT, fb.height);
  if (g.CheckNamedFramebufferStatus(capture_fbo_, GL_DRAW_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    fail("the " + std::to_string(fb.width) + "x" + std::to_string(fb.height) +
         " capture framebuffer (no attachments) is not complete");
  // The node buffers: a list head a pixel (one storage block), and nodes
  // (16 bytes each in the keys, state and colour blocks) for as many
  // fragments as the target has pixels, grown when a draw makes more.
  GLint max_block = 0;
  g.GetIntegerv(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &max_block);
  const uint64_t pixels = uint64_t(fb.width) * uint64_t(fb.height);
  if (kHeadsHeaderWords * 4 + pixels * 4 > uint64_t(max_block))
    fail("the target " + fb.name + " (" + std::to_string(fb.width) + "x" + std::to_string(fb.height) +
         ") has more pixels than a storage block of " + std::to_string(max_block) +
         " bytes (GL_MAX_SHADER_STORAGE_BLOCK_SIZE) has list heads for");
  max_nodes_ = uint64_t(max_block) / 16 / 64 * 64;
  g.CreateBuffers(kCaptureBindings, node_buffers_.data());
  g.NamedBufferData(node_buffers_[0], GLsizeiptr(kHeadsHeaderWords * 4 + pixels * 4), nullptr, GL_DYNAMIC_READ);
  g.CreateTextures(GL_TEXTURE_BUFFER, 2, fetch_textures_.data());
  g.TextureBuffer(fetch_textures_[0], GL_R32UI, node_buffers_[0]);
  // A quarter more nodes than pixels: a draw that covers the target makes
  // a few more fragments than pixels (its triangles share pixels along
  // their edges), and a draw that overflows is drawn again.
  reserve_nodes(std::max<uint64_t>(65536, pixels + pixels / 4));
  g.GenQueries(1, &query_);
  if (reference_msaa_) {
    // The 4x reference: the frame's draws into a multisampled copy.
    GLuint rb[2];
    g.CreateRenderbuffers(2, rb);
    const GLenum colour = fb.encoding == TargetEncoding::kFloat   ? GL_RGBA16F
                          : fb.encoding == TargetEncoding::kSrgb8 ? GL_SRGB8_ALPHA8
                                                                  : GL_RGBA8;
    g.NamedRenderbufferStorageMultisample(rb[0], 4, colour, fb.width, fb.height);
    g.NamedRenderbufferStorageMultisample(rb[1], 4, GL_DEPTH24_STENCIL8, fb.width, fb.height);
    g.CreateFramebuffers(1, &msaa_fbo_);
    g.NamedFramebufferRenderbuffer(msaa_fbo_, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rb[0]);
    g.NamedFramebufferRenderbuffer(msaa_fbo_, GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER, rb[1]);
    if (g.CheckNamedFramebufferStatus(msaa_fbo_, GL_DRAW_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      fail("the 4x multisampled reference framebuffer is not complete");
  }
}

void Session::reserve_nodes(uint64_t nodes) {
  // A multiple of 64 nodes: each sample's depth range starts aligned.
  const GlFunctions& g = real_gl();
  node_capacity_ = std::min<uint64_t>(max_nodes_, (nodes + 63) / 64 * 64);
  for (int b = 1; b <= 3; ++b)
    g.NamedBufferData(node_buffers_[size_t(b)], GLsizeiptr(node_capacity_ * 16), nullptr, GL_DYNAMIC_READ);
  g.TextureBuffer(fetch_textures_[1], GL_RGBA32UI, node_buffers_[1]);  // the keys' new store
  depth_capacity_ = 0;                                                 // sized by the draw's spp at its first pass
}

std::string Session::program_name(GLuint program) const {
  if (program == 0) return "fixed function";
  char label[256] = {};
  GLsizei n = 0;
  real_gl().GetObjectLabel(GL_PROGRAM, program, sizeof label, &n, label);
  if (n > 0) return std::string(label, size_t(n));
  return "program " + std::to_string(program);
}

DrawState Session::read_state(uint32_t index, const FramebufferInfo& fb, std::string& unsupported) const {
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

void Session::linked(GLuint program) {
  const GlFunctions& g = real_gl();
  instrumented_.erase(program);
  GLint count = 0;
  g.GetProgramiv(program, GL_ATTACHED_SHADERS, &count);
  std::vector<GLuint> shaders(size_t(std::max(0, count)));
  if (count > 0) g.GetAttachedShaders(program, count, &count, shaders.data());
  std::vector<ShaderSource> src;
  for (GLuint s : shaders) {
    GLint type = 0, len = 0;
    g.GetShaderiv(s, GL_SHADER_TYPE, &type);
    g.GetShaderiv(s, GL_SHADER_SOURCE_LENGTH, &len);
    std::string text(size_t(std::max(0, len)), '\0');
    GLsizei got = 0;
    if (len > 0) g.GetShaderSource(s, len, &got, text.data());
    text.resize(size_t(got));
    src.push_back({GLenum(type), text});
  }
  sources_[program] = std::move(src);
}

void Session::deleting_program(GLuint program) {
  sources_.erase(program);
  auto it = instrumented_.find(program);
  if (it != instrumented_.end()) {
    for (const Instrumented* ins : {&it->second.plain, &it->second.shading, &it->second.coverage})
      if (ins->program) real_gl().DeleteProgram(ins->program);
    instrumented_.erase(it);
  }
}

ProgramSet& Session::instrumented(GLuint program) {
  auto it = instrumented_.find(program);
  if (it != instrumented_.end()) return it->second;
  ProgramSet& set = instrumented_[program];
  if (!sources_.count(program)) linked(program);  // linked before the library saw it (or never through glLinkProgram)
  build_instrumented(program, sources_[program], "program " + std::to_string(program), binding_, set.plain);
  return set;
}

void Session::build_split(GLuint program, ProgramSet& set) {
  if (set.split_tried) return;
  set.split_tried = true;
  std::vector<ShaderSource> src;
  if (program != 0) {
    src = sources_[program];
  } else {
#if ROPSIM_GLCAPTURE_FIXED_FUNCTION
    for (const auto& [key, ff] : fixed_function_)
      if (&ff == &set) {
        const size_t nul = key.find('\0');
        src = {{GL_VERTEX_SHADER, key.substr(0, nul)}, {GL_FRAGMENT_SHADER, key.substr(nul + 1)}};
      }
#endif
  }
  const std::string who = program ? "program " + std::to_string(program) : "the fixed-function program";
  build_instrumented(program, src, who, binding_, set.shading, ProgramVariant::kShading);
  build_instrumented(program, src, who, binding_, set.coverage, ProgramVariant::kCoverage, fetch_unit_);
}

ProgramSet* Session::fixed_function(std::string& unsupported) {
#if ROPSIM_GLCAPTURE_FIXED_FUNCTION
  const GlFunctions& g = real_gl();
  GlGetters get;
  get.GetIntegerv = reinterpret_cast<decltype(get.GetIntegerv)>(g.GetIntegerv);
  get.GetFloatv = reinterpret_cast<decltype(get.GetFloatv)>(g.GetFloatv);
  get.IsEnabled = reinterpret_cast<decltype(get.IsEnabled)>(g.IsEnabled);
  get.GetTexEnviv = reinterpret_cast<decltype(get.GetTexEnviv)>(g.GetTexEnviv);
  get.GetTexEnvfv = reinterpret_cast<decltype(get.GetTexEnvfv)>(g.GetTexEnvfv);
  get.GetLightfv = reinterpret_cast<decltype(get.GetLightfv)>(g.GetLightfv);
  get.GetTexParameteriv = reinterpret_cast<decltype(get.GetTexParameteriv)>(g.GetTexParameteriv);
  get.GetTexLevelParameteriv = reinterpret_cast<decltype(get.GetTexLevelParameteriv)>(g.GetTexLevelParameteriv);
  get.ActiveTexture = reinterpret_cast<decltype(get.ActiveTexture)>(g.ActiveTexture);
  const FixedFunctionState state = read_fixed_function_state(get);
  unsupported = unsupported_reason(state);
  if (!unsupported.empty()) {
    unsupported = "fixed function: " + unsupported;
    return nullptr;
  }
  const GlslProgram p = fixed_function_program(state);
  const std::string key = p.vertex + '\0' + p.fragment;
  auto it = fixed_function_.find(key);
  if (it == fixed_function_.end()) {
    it = fixed_function_.emplace(key, ProgramSet{}).first;
    build_instrumented(0, {{GL_VERTEX_SHADER, p.vertex}, {GL_FRAGMENT_SHADER, p.fragment}},
                       "the fixed-function program", binding_, it->second.plain);
  }
  return &it->second;
#else
  unsupported = "a fixed-function draw: the library is built without the fixed-function module (ff_program.h)";
  return nullptr;
#endif
}

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

void Session::bind_nodes(int sample) {
  const GlFunctions& g = real_gl();
  const GLsizeiptr nodes = GLsizeiptr(node_capacity_ * 16);
  g.BindBufferRange(GL_SHADER_STORAGE_BUFFER, GLuint(binding_), node_buffers_[0], 0,
                    GLsizeiptr(kHeadsHeaderWords * 4 + uint64_t(target_.width) * uint64_t(target_.height) * 4));
  for (int b = 1; b <= 3; ++b)
    g.BindBufferRange(GL_SHADER_STORAGE_BUFFER, GLuint(binding_ + b), node_buffers_[size_t(b)], 0, nodes);
  if (depth_capacity_ >= uint64_t(sample + 1) * node_capacity_)
    g.BindBufferRange(GL_SHADER_STORAGE_BUFFER, GLuint(binding_ + 4), node_buffers_[4],
                      GLintptr(uint64_t(sample) * node_capacity_ * 4), GLsizeiptr(node_capacity_ * 4));
  else  // the 4x reference before any capture pass: bound, never written
    g.BindBufferBase(GL_SHADER_STORAGE_BUFFER, GLuint(binding_ + 4), node_buffers_[4]);
}

void Session::attach_capture_stencil() {
  if (capture_stencil_) return;
  capture_stencil_ = true;
  const GlFunctions& g = real_gl();
  GLuint rb = 0;
  g.CreateRenderbuffers(1, &rb);
  g.NamedRenderbufferStorage(rb, GL_DEPTH32F_STENCIL8, target_.width, target_.height);
  g.NamedFramebufferRenderbuffer(capture_fbo_, GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER, rb);
  if (g.CheckNamedFramebufferStatus(capture_fbo_, GL_DRAW_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    fail("the capture framebuffer with its " + std::to_string(target_.width) + "x" + std::to_string(target_.height) +
         " stencil buffer is not complete");
}

void Session::split_pass(const ProgramSet& set, int s, std::array<float, 2> off, std::array<float, 2> pixel_off,
                         const std::vector<DrawCallPart>& parts) {
  const GlFunctions& g = real_gl();
  // The coverage pass: a fragment without a node (the coverage twin keeps
  // it) counts itself in its pixel's stencil and writes its depth.
  const GLint zero = 0;
  // Under the application's scissor, as the passes: outside it no fragment reads the stencil.
  g.ClearNamedFramebufferiv(capture_fbo_, GL_STENCIL, 0, &zero);
  const Instrumented& cov = set.coverage;
  g.UseProgram(cov.program);
  g.ProgramUniform2f(cov.program, cov.loc_offset, off[0], off[1]);
  g.Enable(GL_STENCIL_TEST);
  g.Enable(GL_DEPTH_TEST);
  g.DepthFunc(GL_ALWAYS);
  g.DepthMask(GL_TRUE);
  g.StencilFuncSeparate(GL_FRONT_AND_BACK, GL_ALWAYS, 0, 0xFF);
  g.StencilOpSeparate(GL_FRONT_AND_BACK, GL_KEEP, GL_KEEP, GL_INCR);
  for (size_t k = 0; k < parts.size(); ++k) {
    if (cov.loc_part >= 0) g.ProgramUniform1ui(cov.program, cov.loc_part, GLuint(k));
    parts[k].replay();
  }
  g.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);  // the coverage pass's depths before the shading passes
  // The shading passes, tested before the shader: where one fragment of the
  // pixel has no node, only the fragments at its depth (it, and any other
  // at the same depth, which finds its node and shades nothing); where
  // several have none, every fragment of the pixel.
  const Instrumented& sh = set.shading;
  g.UseProgram(sh.program);
  g.ProgramUniform2f(sh.program, sh.loc_offset, off[0], off[1]);
  if (sh.loc_pixel_offset >= 0) g.ProgramUniform2f(sh.program, sh.loc_pixel_offset, pixel_off[0], pixel_off[1]);
  g.ProgramUniform1i(sh.program, sh.loc_pass, int(PassKind::kSample));
  if (sh.loc_sample >= 0) g.ProgramUniform1ui(sh.program, sh.loc_sample, GLuint(s));
  g.DepthMask(GL_FALSE);
  g.StencilOpSeparate(GL_FRONT_AND_BACK, GL_KEEP, GL_KEEP, GL_KEEP);
  for (int several = 0; several < 2; ++several) {
    g.DepthFunc(several ? GL_ALWAYS : GL_EQUAL);
    g.StencilFuncSeparate(GL_FRONT_AND_BACK, several ? GL_LESS : GL_EQUAL, 1, 0xFF);  // 1 < stencil; 1 == stencil
    for (size_t k = 0; k < parts.size(); ++k) {
      if (sh.loc_part >= 0) g.ProgramUniform1ui(sh.program, sh.loc_part, GLuint(k));
      parts[k].replay();
    }
  }
  g.Disable(GL_STENCIL_TEST);
  g.Disable(GL_DEPTH_TEST);
}

void Session::capture_draw(GLuint program, const ProgramSet& set, const std::vector<DrawCallPart>& parts,
                           DrawRecord& d) {
  const GlFunctions& g = real_gl();
  const Instrumented& ins = set.plain;
  for (const auto& b : ins.storage_blocks) {
    const GLenum prop = GL_BUFFER_BINDING;
    GLint binding = 0;
    g.GetProgramResourceiv(program, GL_SHADER_STORAGE_BLOCK, b.first, 1, &prop, 1, nullptr, &binding);
    if (binding >= binding_ && binding < binding_ + kCaptureBindings)
      fail("program " + std::to_string(program) + ": a storage block uses binding " + std::to_string(binding) +
           ", one of those the capture keeps its fragments in (" + std::to_string(binding_) + ".." +
           std::to_string(binding_ + kCaptureBindings - 1) + ")");
  }
  // An occlusion query of the application's own would count the passes.
  GLint app_query = 0;
  g.GetQueryiv(GL_SAMPLES_PASSED, GL_CURRENT_QUERY, &app_query);
  const bool count = count_samples_ && app_query == 0;
  // Above 1 spp (and unless the passes are counted) each sample pass is a
  // coverage pass with the coverage twin, which marks in the stencil buffer
  // the pixels of fragments that have no node yet, and a shading pass with
  // the shading twin at the same shift, culled to those pixels by the
  // stencil test before the shader.
  const bool split = !count && spp_ > 1 && set.split();
  if (split) attach_capture_stencil();

  SavedState saved;
  saved.save(binding_);
  g.BindFramebuffer(GL_DRAW_FRAMEBUFFER, capture_fbo_);
  g.Disable(GL_DEPTH_TEST);
  g.Disable(GL_STENCIL_TEST);
  g.Disable(GL_BLEND);
  g.ColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
  g.UseProgram(ins.program);
  for (const Instrumented* p : {&ins, &set.shading, &set.coverage}) {
    if (!p->program || (p != &ins && !split)) continue;
    copy_uniforms(program, *p);
    g.ProgramUniform1i(p->program, p->loc_upside_down, 0);
    // With the counts a sample pass shades every fragment (its query counts
    // those the shader keeps), else only those it gives the colour of.
    if (p->loc_gate >= 0) g.ProgramUniform1i(p->program, p->loc_gate, count ? 0 : 1);
  }
  // The coverage passes' buffer textures on the last two units (the
  // application's bindings there restored after the passes).
  GLint active_unit = GL_TEXTURE0;
  std::array<GLint, 2> unit_texture{};
  if (split) {
    g.StencilMaskSeparate(GL_FRONT_AND_BACK, 0xFF);
    g.GetIntegerv(GL_ACTIVE_TEXTURE, &active_unit);
    for (int k = 0; k < 2; ++k) {
      g.ActiveTexture(GLenum(GL_TEXTURE0 + fetch_unit_ + k));
      g.GetIntegerv(GL_TEXTURE_BINDING_BUFFER, &unit_texture[size_t(k)]);
      g.BindTexture(GL_TEXTURE_BUFFER, fetch_textures_[size_t(k)]);
    }
  }
  GLint vp[4] = {};
  g.GetIntegerv(GL_VIEWPORT, vp);
  const std::array<SamplePos, 64> positions = standard_sample_positions(spp_);
  // The centre pass first: it makes the nodes of the fragments whose
  // primitive covers the pixel centre and shades them; then the sample
  // passes in sample order, so that a pass knows whether its sample is a
  // node's lowest covered one.
  std::vector<int> order;
  if (needs_centre_pass(positions, spp_)) order.push_back(kCentrePass);
  for (int s = 0; s < spp_; ++s) order.push_back(s);
  uint64_t passed = 0, made = 0;
  for (;;) {
    if (depth_capacity_ < uint64_t(spp_) * node_capacity_) {
      depth_capacity_ = uint64_t(spp_) * node_capacity_;
      g.NamedBufferData(node_buffers_[4], GLsizeiptr(depth_capacity_ * 4), nullptr, GL_DYNAMIC_READ);
    }
    g.MemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);  // the previous draw's nodes read before the reset
    const uint32_t empty = kNoNode;
    g.ClearNamedBufferData(node_buffers_[0], GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &empty);
    const uint32_t zero[kHeadsHeaderWords] = {};
    g.NamedBufferSubData(node_buffers_[0], 0, sizeof zero, zero);
    // Every sample uncovered until a pass writes its depth.
    g.ClearNamedBufferSubData(node_buffers_[4], GL_R32UI, 0, GLsizeiptr(uint64_t(spp_) * node_capacity_ * 4),
                              GL_RED_INTEGER, GL_UNSIGNED_INT, &kNoDepth);
    for (const Instrumented* p : {&ins, &set.shading, &set.coverage}) {
      if (!p->program || (p != &ins && !split)) continue;
      if (p->loc_capacity >= 0) g.ProgramUniform1ui(p->program, p->loc_capacity, GLuint(node_capacity_));
      if (p->loc_width >= 0) g.ProgramUniform1ui(p->program, p->loc_width, GLuint(target_.width));
    }
    passed = 0;
    const auto t = std::chrono::steady_clock::now();
    for (const int s : order) {
      const std::array<float, 2> off =
          s == kCentrePass ? std::array<float, 2>{0.0f, 0.0f}
                           : sample_clip_offset(positions[size_t(s)], std::max(1, vp[2]), std::max(1, vp[3]));
      // The shift in pixels: the fragment shader reads its inputs there, at
      // the pixel centre of the unshifted geometry, where multisampling shades.
      const std::array<float, 2> pixel_off = {off[0] * 0.5f * float(std::max(1, vp[2])),
                                              off[1] * 0.5f * float(std::max(1, vp[3]))};
      bind_nodes(s == kCentrePass ? 0 : s);
      if (split && s != kCentrePass) {
        split_pass(set, s, off, pixel_off, parts);
        continue;
      }
      g.UseProgram(ins.program);
      g.ProgramUniform2f(ins.program, ins.loc_offset, off[0], off[1]);
      if (ins.loc_pixel_offset >= 0) g.ProgramUniform2f(ins.program, ins.loc_pixel_offset, pixel_off[0], pixel_off[1]);
      g.ProgramUniform1i(ins.program, ins.loc_pass, int(s == kCentrePass ? PassKind::kCentre : PassKind::kSample));
      if (ins.loc_sample >= 0) g.ProgramUniform1ui(ins.program, ins.loc_sample, GLuint(s == kCentrePass ? 0 : s));
      for (size_t k = 0; k < parts.size(); ++k) {
        if (ins.loc_part >= 0) g.ProgramUniform1ui(ins.program, ins.loc_part, GLuint(k));
        if (count && s != kCentrePass) g.BeginQuery(GL_SAMPLES_PASSED, query_);
        parts[k].replay();
        if (count && s != kCentrePass) {  // the centre pass adds colour, no coverage
          g.EndQuery(GL_SAMPLES_PASSED);
          GLuint64 r = 0;
          g.GetQueryObjectui64v(query_, GL_QUERY_RESULT, &r);
          passed += r;
        }
      }
      g.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT |
                      GL_TEXTURE_FETCH_BARRIER_BIT);  // a pass's nodes before the next pass
    }
    g.MemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    uint32_t n = 0;
    g.GetNamedBufferSubData(node_buffers_[0], 0, 4, &n);  // waits for the passes
    times_s_.passes += seconds_since(t);
    made = n;
    if (made <= node_capacity_) break;
    if (made > max_nodes_)
      fail("draw " + std::to_string(d.index) + " (" + d.name + "): it makes " + std::to_string(made) +
           " fragments, more than the " + std::to_string(max_nodes_) +
           " nodes a storage block holds (GL_MAX_SHADER_STORAGE_BLOCK_SIZE)");
    reserve_nodes(made + made / 8);  // and the draw's passes again
  }
  saved.restore(binding_);
  if (split) {
    for (int k = 0; k < 2; ++k) {
      g.ActiveTexture(GLenum(GL_TEXTURE0 + fetch_unit_ + k));
      g.BindTexture(GL_TEXTURE_BUFFER, GLuint(unit_texture[size_t(k)]));
    }
    g.ActiveTexture(GLenum(active_unit));
  }

  // The nodes read in place (mapped).
  auto t = std::chrono::steady_clock::now();
  NodeView nodes;
  nodes.count = size_t(made);
  nodes.spp = spp_;
  std::array<const void*, kCaptureBindings> mapped{};
  if (made) {
    for (int b = 1; b <= 3; ++b)
      mapped[size_t(b)] = g.MapNamedBufferRange(node_buffers_[size_t(b)], 0, GLsizeiptr(made * 16), GL_MAP_READ_BIT);
    mapped[4] =
        g.MapNamedBufferRange(node_buffers_[4], 0, GLsizeiptr(uint64_t(spp_) * node_capacity_ * 4), GL_MAP_READ_BIT);
    for (int b = 1; b <= 4; ++b)
      if (!mapped[size_t(b)]) fail("draw " + std::to_string(d.index) + " (" + d.name + "): the nodes cannot be mapped");
    nodes.keys = static_cast<const uint32_t*>(mapped[1]);
    nodes.state = static_cast<const uint32_t*>(mapped[2]);
    nodes.colour = static_cast<const float*>(mapped[3]);
    for (int s = 0; s < spp_; ++s)
      nodes.depth[size_t(s)] = static_cast<const uint32_t*>(mapped[4]) + uint64_t(s) * node_capacity_;
  }
  times_s_.read_back += seconds_since(t);
  std::vector<DrawPart> shape;
  for (const DrawCallPart& p : parts) shape.push_back({p.prims_per_instance});
  EncodedDraw draw;  // a draw's own: no earlier draw's fragments move
  const bool clamp = target_.encoding != TargetEncoding::kFloat;
  // The records' layout (the trace's header, less what the frame's end knows).
  TraceHeader layout;
  layout.width = uint32_t(target_.width);
  layout.height = uint32_t(target_.height);
  layout.spp = spp_;
  layout.depth_mode = DepthMode::kPerSample;
  layout.color_format = ColorFormat::kRgbF32;
  t = std::chrono::steady_clock::now();
  const std::string err = made ? build_records(nodes, d.trace_id, shape, clamp, layout, draw) : "";
  if (made)
    for (int b = 1; b <= 4; ++b) g.UnmapNamedBuffer(node_buffers_[size_t(b)]);
  if (!err.empty()) fail(err);
  times_s_.build += seconds_since(t);
  d.fragments = draw.count;
  d.covered_samples = draw.covered_samples;
  if (!list_only_) records_.push_back(std::move(draw));  // else counted, no trace to write
  d.counted = count;
  d.samples_passed = passed;
}

void Session::render_passes(const std::vector<DrawCallPart>& parts) {
  // What llvmpipe does for the capture's passes without the capture's own
  // work: the draw re-executed once per pass with the application's program
  // and state (no record, no read-back) into a colour buffer of the
  // target's size and format, with no depth or stencil buffer (as the
  // capture framebuffer: no fragment is tested away). A colour buffer, not
  // the capture framebuffer's none: with no output llvmpipe compiles the
  // fragment shader away and only rasterizes. The geometry moves by a
  // fractional viewport instead of the instrumented vertex shader's offset.
  const GlFunctions& g = real_gl();
  if (!render_fbo_) {
    GLuint rb = 0;
    g.CreateRenderbuffers(1, &rb);
    g.NamedRenderbufferStorage(rb,
                               target_.encoding == TargetEncoding::kFloat   ? GL_RGBA16F
                               : target_.encoding == TargetEncoding::kSrgb8 ? GL_SRGB8_ALPHA8
                                                                            : GL_RGBA8,
                               target_.width, target_.height);
    g.CreateFramebuffers(1, &render_fbo_);
    g.NamedFramebufferRenderbuffer(render_fbo_, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rb);
    if (g.CheckNamedFramebufferStatus(render_fbo_, GL_DRAW_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      fail("the pass-rendering framebuffer (ROPSIM_GL_RENDER_PASSES) is not complete");
  }
  GLint draw_fbo = 0;
  g.GetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &draw_fbo);
  g.BindFramebuffer(GL_DRAW_FRAMEBUFFER, render_fbo_);
  GLint vp[4] = {};
  g.GetIntegerv(GL_VIEWPORT, vp);
  const std::array<SamplePos, 64> positions = standard_sample_positions(spp_);
  const int passes = spp_ + (needs_centre_pass(positions, spp_) ? 1 : 0);
  const auto t = std::chrono::steady_clock::now();
  for (int pass = 0; pass < passes; ++pass) {
    const int s = pass < spp_ ? pass : kCentrePass;
    const std::array<float, 2> off =
        s == kCentrePass ? std::array<float, 2>{0.0f, 0.0f}
                         : sample_clip_offset(positions[size_t(s)], std::max(1, vp[2]), std::max(1, vp[3]));
    g.ViewportIndexedf(0, float(vp[0]) + off[0] * 0.5f * float(vp[2]), float(vp[1]) + off[1] * 0.5f * float(vp[3]),
                       float(vp[2]), float(vp[3]));
    for (const DrawCallPart& p : parts) p.replay();
  }
  g.Finish();
  times_s_.passes += seconds_since(t);
  g.Viewport(vp[0], vp[1], vp[2], vp[3]);
  g.BindFramebuffer(GL_DRAW_FRAMEBUFFER, GLuint(draw_fbo));
}

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

void Session::reference_draw(GLuint program, const Instrumented& ins, const std::vector<DrawCallPart>& parts) {
  // The application's state but the framebuffer, drawn upside down with the
  // instrumented program recording nothing (pass kind none): GL window row y is
  // then trace row y, and llvmpipe's 4 sample positions are the header's.
  const GlFunctions& g = real_gl();
  GLint current = 0;
  g.GetIntegerv(GL_CURRENT_PROGRAM, &current);
  SavedBindings bindings;
  bindings.save(binding_);
  FlippedState flipped;
  flipped.flip(msaa_fbo_, target_.height);
  g.UseProgram(ins.program);
  copy_uniforms(program, ins);
  g.ProgramUniform2f(ins.program, ins.loc_offset, 0.0f, 0.0f);
  if (ins.loc_pixel_offset >= 0) g.ProgramUniform2f(ins.program, ins.loc_pixel_offset, 0.0f, 0.0f);
  g.ProgramUniform1i(ins.program, ins.loc_upside_down, 1);
  g.ProgramUniform1ui(ins.program, ins.loc_capacity, 0);
  // Pass kind none: the shader touches none of the node buffers (bound all
  // the same, as the program declares them).
  g.ProgramUniform1i(ins.program, ins.loc_pass, int(PassKind::kNone));
  if (ins.loc_gate >= 0) g.ProgramUniform1i(ins.program, ins.loc_gate, 0);
  bind_nodes(0);
  for (const DrawCallPart& p : parts) p.replay();
  flipped.restore();
  g.UseProgram(GLuint(current));
  bindings.restore(binding_);
}

void Session::set_alpha_test(const Instrumented& ins, bool on) {
  // A GLSL program's draw with GL_ALPHA_TEST on (a compatibility context):
  // the wrapper applies the test before its record, as GL does after the
  // shader (glsl_rewrite.cpp). Off, and for the fixed-function programs,
  // which apply it themselves: function 0.
  const GlFunctions& g = real_gl();
  GLint func = 0;
  GLfloat ref = 0, one = 0;
  if (on) {
    g.GetIntegerv(GL_ALPHA_TEST_FUNC, &func);
    func = func >= GL_NEVER && func <= GL_ALWAYS ? func - GL_NEVER + 1 : 8;
    g.GetFloatv(GL_ALPHA_TEST_REF, &ref);
    ref = std::isnan(ref) ? 0.0f : std::clamp(ref, 0.0f, 1.0f);
    GLint bits = 0;  // the application's target, bound now: llvmpipe compares in its precision up to 8 bits
    g.GetIntegerv(GL_RED_BITS, &bits);
    if (bits >= 1 && bits <= 8) {
      one = float((1 << bits) - 1);
      ref = std::nearbyint(ref * one);  // ties to even in the default rounding mode, as roundEven
    }
  }
  if (ins.loc_alpha_func >= 0) g.ProgramUniform1i(ins.program, ins.loc_alpha_func, func);
  if (ins.loc_alpha_ref >= 0) g.ProgramUniform1fv(ins.program, ins.loc_alpha_ref, 1, &ref);
  if (ins.loc_alpha_one >= 0) g.ProgramUniform1fv(ins.program, ins.loc_alpha_one, 1, &one);
}

void Session::draw(const std::function<void()>& app, const std::vector<DrawCallPart>& parts) {
  const GlFunctions& g = real_gl();
  GLint fbo = 0, program = 0, pipeline = 0;
  g.GetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &fbo);
  g.GetIntegerv(GL_CURRENT_PROGRAM, &program);
  FramebufferInfo& fb = framebuffer(fbo);
  DrawRecord d;
  d.index = uint32_t(draws_.size());
  d.framebuffer = fb.name;
  d.program = GLuint(program);
  d.name = program_name(d.program);
  ++fb.draws;
  std::string unsupported;
  if (is_target(fbo)) {
    use_target(fb);
    d.target = true;
    d.trace_id = target_draws_++;
    d.state = read_state(d.trace_id, fb, unsupported);
    d.state.name = d.name.size() > 255 ? d.name.substr(0, 255) : d.name;
  } else {
    d.state = default_draw_state(d.index);
  }
  app();
  if (!d.target) {
    draws_.push_back(d);
    return;
  }
  ProgramSet* set = nullptr;
  if (unsupported.empty() && program == 0) {
    g.GetIntegerv(GL_PROGRAM_PIPELINE_BINDING, &pipeline);
    if (pipeline != 0)
      unsupported = "a separable program pipeline cannot be instrumented";
    else
      set = fixed_function(unsupported);
  } else if (unsupported.empty() && (msaa_fbo_ || !list_only_ || count_samples_)) {
    set = &instrumented(GLuint(program));  // a list without counts re-executes nothing
  }
  if (set && !set->plain.error.empty()) fail(set->plain.error);
  // The split sample passes' twins: above 1 spp when the passes are not counted.
  if (set && spp_ > 1 && !list_only_ && !count_samples_) build_split(GLuint(program), *set);
  const bool alpha_test = program != 0 && compatibility_ && g.IsEnabled(GL_ALPHA_TEST);
  if (set)
    for (const Instrumented* p : {&set->plain, &set->shading})
      if (p->program) set_alpha_test(*p, alpha_test);
  GLboolean tf = GL_FALSE;
  g.GetBooleanv(GL_TRANSFORM_FEEDBACK_ACTIVE, &tf);
  if (unsupported.empty() && tf) unsupported = "transform feedback is active (re-executing would append to it)";
  if (!unsupported.empty()) {
    unsupported_.push_back({d.index, d.name, unsupported});
  } else if (!g.IsEnabled(GL_RASTERIZER_DISCARD)) {  // a discarded rasterizer draws nothing: no fragments
    if (msaa_fbo_) reference_draw(GLuint(program), set->plain, parts);
    // ROPSIM_GL_LIST_ONLY: the passes only when the counts are asked for (ROPSIM_GL_COUNT_SAMPLES)
    if (!list_only_ || count_samples_)
      capture_draw(GLuint(program), *set, parts, d);
    else if (render_passes_)
      render_passes(parts);
  }
  draws_.push_back(std::move(d));
}

void Session::unsupported_draw(const char* reason) {
  const GlFunctions& g = real_gl();
  GLint fbo = 0, program = 0;
  g.GetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &fbo);
  g.GetIntegerv(GL_CURRENT_PROGRAM, &program);
  FramebufferInfo& fb = framebuffer(fbo);
  DrawRecord d;
  d.index = uint32_t(draws_.size());
  d.framebuffer = fb.name;
  d.program = GLuint(program);
  d.name = program_name(d.program);
  ++fb.draws;
  if (is_target(fbo)) {
    use_target(fb);
    std::string ignored;
    d.target = true;
    d.trace_id = target_draws_++;
    d.state = read_state(d.trace_id, fb, ignored);
    d.state.name = d.name.size() > 255 ? d.name.substr(0, 255) : d.name;
    unsupported_.push_back({d.index, d.name, reason});
  } else {
    d.state = default_draw_state(d.index);
  }
  draws_.push_back(std::move(d));
}

void Session::clear(GLbitfield mask) {
  const GlFunctions& g = real_gl();
  GLint fbo = 0;
  g.GetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &fbo);
  if (!is_target(fbo)) return;
  use_target(framebuffer(fbo));
  const bool drawn = std::any_of(draws_.begin(), draws_.end(), [](const DrawRecord& d) { return d.target; });
  if ((mask & GL_COLOR_BUFFER_BIT) && !color_cleared_ && !drawn) {
    GLfloat c[4] = {};
    g.GetFloatv(GL_COLOR_CLEAR_VALUE, c);
    for (int i = 0; i < 3; ++i) {
      float v = std::isfinite(c[i]) ? std::max(0.0f, c[i]) : 0.0f;
      clear_color_[size_t(i)] = target_.encoding == TargetEncoding::kFloat ? v : std::min(1.0f, v);
    }
    color_cleared_ = true;
  }
  if ((mask & GL_DEPTH_BUFFER_BIT) && !depth_cleared_ && !drawn) {
    GLfloat z = 1.0f;
    g.GetFloatv(GL_DEPTH_CLEAR_VALUE, &z);
    clear_depth_ = std::min(1.0f, std::max(0.0f, z));
    depth_cleared_ = true;
  }
  if (msaa_fbo_) {
    FlippedState flipped;
    flipped.flip(msaa_fbo_, target_.height);
    g.Clear(mask);
    flipped.restore();
  }
}

std::vector<uint8_t> Session::read_target(GLint fbo, bool presented, int w, int h, bool upside_down) const {
  const GlFunctions& g = real_gl();
  g.BindFramebuffer(GL_READ_FRAMEBUFFER, GLuint(fbo));
  if (presented) {
    GLboolean doublebuffer = GL_TRUE;
    g.GetBooleanv(GL_DOUBLEBUFFER, &doublebuffer);
    g.ReadBuffer(doublebuffer ? GL_BACK : GL_FRONT);
  } else {
    g.ReadBuffer(GL_COLOR_ATTACHMENT0);
  }
  g.BindBuffer(GL_PIXEL_PACK_BUFFER, 0);
  g.PixelStorei(GL_PACK_ALIGNMENT, 1);
  g.PixelStorei(GL_PACK_ROW_LENGTH, 0);
  g.PixelStorei(GL_PACK_SKIP_ROWS, 0);
  g.PixelStorei(GL_PACK_SKIP_PIXELS, 0);
  std::vector<uint8_t> up(size_t(w) * size_t(h) * 4), down(up.size());
  g.ReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, up.data());
  // GL's rows run bottom-up; the files' run top-down, as the trace's.
  const size_t row = size_t(w) * 4;
  if (upside_down) return up;  // drawn upside down: GL's rows already run top-down
  for (int y = 0; y < h; ++y) std::memcpy(&down[size_t(y) * row], &up[size_t(h - 1 - y) * row], row);
  return down;
}

void Session::finish_frame() {
  finished_ = true;
  frames_seen_ += 1;
  const GlFunctions& g = real_gl();
  if (!target_known_) {
    if (!target_presented_)
      fail("ROPSIM_GL_TARGET=" + target_text_ + ": frame " + std::to_string(frame_) +
           " neither draws into nor clears framebuffer object " + std::to_string(target_fbo_));
    // Nothing drew into the presented framebuffer this frame: its size from the window system.
    use_target(query_framebuffer(target_presented_ ? 0 : GLint(target_fbo_)));
    framebuffers_.push_back(target_);
  }
  std::string err;
  const std::vector<uint8_t> frame =
      read_target(target_presented_ ? 0 : GLint(target_fbo_), target_presented_, target_.width, target_.height);
  if (!write_file_atomic(dir_ + "/frame.rgba", frame.data(), frame.size(), err)) fail(err);
  const json frame_json = {{"width", target_.width},
                           {"height", target_.height},
                           {"format", "rgba8"},
                           {"encoding", encoding_name(target_.encoding)},
                           {"rows", "top-down"}};
  if (!write_json(dir_ + "/frame.json", frame_json, err)) fail(err);
  if (msaa_fbo_) {
    GLuint rb = 0, resolved = 0;
    g.CreateRenderbuffers(1, &rb);
    g.NamedRenderbufferStorage(rb, target_.encoding == TargetEncoding::kSrgb8 ? GL_SRGB8_ALPHA8 : GL_RGBA8,
                               target_.width, target_.height);
    g.CreateFramebuffers(1, &resolved);
    g.NamedFramebufferRenderbuffer(resolved, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rb);
    g.BlitNamedFramebuffer(msaa_fbo_, resolved, 0, 0, target_.width, target_.height, 0, 0, target_.width,
                           target_.height, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    const std::vector<uint8_t> ref = read_target(GLint(resolved), false, target_.width, target_.height, true);
    if (!write_file_atomic(dir_ + "/frame-msaa4.rgba", ref.data(), ref.size(), err)) fail(err);
  }
  if (!list_only_) {
    TraceHeader h;
    h.width = uint32_t(target_.width);
    h.height = uint32_t(target_.height);
    h.spp = spp_;
    h.depth_mode = DepthMode::kPerSample;
    h.color_format = ColorFormat::kRgbF32;
    h.compression = Compression::kZstd;
    h.clear_color = clear_color_;
    h.clear_depth = clear_depth_;
    h.positions = standard_sample_positions(spp_);
    char exe[256] = {};
    const ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    std::string app = n > 0 ? std::string(exe, size_t(n)) : "application";
    app = app.substr(app.rfind('/') + 1);
    h.scene_name = "gl " + app + " frame " + std::to_string(frame_);
    std::vector<DrawState> states;
    for (const DrawRecord& d : draws_)
      if (d.target) states.push_back(d.state);
    h.draws = DrawTable(std::move(states));
    if (const std::string why = h.draws.validate(); !why.empty()) fail("the draw states: " + why);
    const auto t = std::chrono::steady_clock::now();
    try {
      TraceWriter w(out_, h, kTraceZstdLevel, kTraceZstdWorkers);
      for (const EncodedDraw& draw : records_) w.write_records(draw.bytes.data(), draw.bytes.size(), draw.count);
      w.finish();
    } catch (const std::exception& e) {
      fail(e.what());
    }
    times_s_.write += seconds_since(t);
  }
  if (!times_.empty()) {
    const json j = {{"passes", times_s_.passes},
                    {"read_back", times_s_.read_back},
                    {"build", times_s_.build},
                    {"write", times_s_.write}};
    if (!write_json(times_, j, err)) fail(err);
  }
  if (!write_json(dir_ + "/list.json", list_json(), err)) fail(err);
  if (!write_status(true, "")) _exit(1);
  std::fflush(stdout);
  _exit(0);
}

void Session::swap() {
  if (finished_) return;
  if (capturing()) {
    finish_frame();
    return;
  }
  ++frames_seen_;
}

void Session::destroying_context(const void* context) {
  contexts_.erase(context);
  if (contexts_.empty() && !finished_) at_exit();
}

void Session::at_exit() {
  if (finished_ || !used_gl_) return;
  write_status(false, "the application exited after " + std::to_string(frames_seen_) + " frames, before frame " +
                          std::to_string(frame_));
}

Session* g_session = nullptr;

void session_at_exit() {
  if (g_session) g_session->at_exit();
}

__attribute__((constructor)) void start_session() {
  if (!std::getenv("ROPSIM_GL_CONTROL")) return;
  g_session = new Session();
  std::atexit(session_at_exit);
}

}  // namespace

CaptureSession* session() { return g_session; }

}  // namespace ropsim::glcapture
