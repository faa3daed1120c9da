#include "traces/glcapture/capture_session.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>

#include "traces/glcapture/gl_functions.h"
#include "traces/glcapture/session.h"

#if ROPSIM_GLCAPTURE_FIXED_FUNCTION
#include "traces/glcapture/ff_program.h"
#endif

namespace ropsim::glcapture {

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

}  // namespace

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

FramebufferInfo& Session::framebuffer(GLint fbo) {
  for (FramebufferInfo& f : framebuffers_)
    if (f.fbo == fbo) return f;
  framebuffers_.push_back(query_framebuffer(fbo));
  return framebuffers_.back();
}

std::string Session::program_name(GLuint program) const {
  if (program == 0) return "fixed function";
  char label[256] = {};
  GLsizei n = 0;
  real_gl().GetObjectLabel(GL_PROGRAM, program, sizeof label, &n, label);
  if (n > 0) return std::string(label, size_t(n));
  return "program " + std::to_string(program);
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
    d.state = read_draw_state(d.trace_id, fb, unsupported);
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
    d.state = read_draw_state(d.trace_id, fb, ignored);
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

namespace {

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
