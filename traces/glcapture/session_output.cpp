#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

#include "traces/format/trace.h"
#include "traces/glcapture/gl_functions.h"
#include "traces/glcapture/session.h"
#include "traces/raster/sample_patterns.h"

namespace ropsim::glcapture {

/// The trace's zstd level: 1, not the writer's default 3 (jellyfish's
/// 1920 x 1080 16-spp frame, 308 MB of records, compresses in 0.5 s instead
/// of 0.85 s, into a trace 2 % larger).
constexpr int kTraceZstdLevel = 1;
/// zstd's compression threads for the trace: a fixed count (not the
/// machine's), so that the trace's bytes are the same on every machine.
constexpr int kTraceZstdWorkers = 2;

TraceHeader Session::trace_layout() const {
  TraceHeader h;
  h.width = uint32_t(target_.width);
  h.height = uint32_t(target_.height);
  h.spp = spp_;
  h.depth_mode = DepthMode::kPerSample;
  h.color_format = ColorFormat::kRgbF32;
  h.compression = Compression::kZstd;
  h.positions = standard_sample_positions(spp_);
  return h;
}

TraceWriter& Session::trace() {
  if (!trace_) {
    try {
      trace_ = std::make_unique<TraceWriter>(out_, trace_layout(), kTraceZstdLevel, kTraceZstdWorkers,
                                             TraceWriter::HeaderLast{});
    } catch (const std::exception& e) {
      fail(e.what());
    }
  }
  return *trace_;
}

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
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
    TraceHeader h = trace_layout();
    h.clear_color = clear_color_;
    h.clear_depth = clear_depth_;
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
    // The records are framed and compressed already: the header, then them.
    try {
      trace().finish(h);
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

}  // namespace ropsim::glcapture
