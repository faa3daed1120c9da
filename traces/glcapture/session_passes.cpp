#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>

#include "traces/glcapture/fragment_order.h"
#include "traces/glcapture/gl_functions.h"
#include "traces/glcapture/session.h"
#include "traces/raster/sample_patterns.h"

namespace ropsim::glcapture {

namespace {

/// A positive node count from the environment variable `name`, else 0.
uint64_t env_nodes(const char* name) {
  const char* v = std::getenv(name);
  if (!v || !*v) return 0;
  char* end = nullptr;
  const unsigned long long n = std::strtoull(v, &end, 10);
  return *end ? 0 : uint64_t(n);
}

// The library's own storage block bindings (the last kCaptureBindings): an
// application program that binds a block there cannot be captured.
GLint capture_binding() {
  GLint n = 0;
  real_gl().GetIntegerv(GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS, &n);
  return std::max(0, n - kCaptureBindings);
}

}  // namespace

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
  // (16 bytes each in the keys and colour blocks, 4 in the state's) for as many
  // fragments as the target has pixels, grown when a draw makes more.
  GLint max_block = 0;
  g.GetIntegerv(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &max_block);
  const uint64_t pixels = uint64_t(fb.width) * uint64_t(fb.height);
  if (kHeadsHeaderWords * 4 + pixels * 4 > uint64_t(max_block))
    fail("the target " + fb.name + " (" + std::to_string(fb.width) + "x" + std::to_string(fb.height) +
         ") has more pixels than a storage block of " + std::to_string(max_block) +
         " bytes (GL_MAX_SHADER_STORAGE_BLOCK_SIZE) has list heads for");
  // Lists a pixel (a fragment's by its primitive, instance and part): 4
  // where the heads fit a storage block and a buffer texture, so that the
  // walks are a quarter as long where primitives overlap.
  GLint max_texels = 0;
  g.GetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &max_texels);
  lists_ = 4;
  while (lists_ > 1 && (kHeadsHeaderWords * 4 + pixels * lists_ * 4 > uint64_t(max_block) ||
                        kHeadsHeaderWords + pixels * lists_ > uint64_t(max_texels)))
    lists_ /= 2;
  max_nodes_ = uint64_t(max_block) / 16 / 64 * 64;
  GLint extensions = 0;
  g.GetIntegerv(GL_NUM_EXTENSIONS, &extensions);
  for (GLint i = 0; i < extensions && !pinned_; ++i) {
    const char* e = reinterpret_cast<const char*>(g.GetStringi(GL_EXTENSIONS, GLuint(i)));
    pinned_ = e && std::strcmp(e, "GL_AMD_pinned_memory") == 0;
  }
  g.CreateBuffers(kCaptureBindings, node_buffers_.data());
  node_store(0, heads_bytes());
  g.CreateTextures(GL_TEXTURE_BUFFER, 2, fetch_textures_.data());
  g.TextureBuffer(fetch_textures_[0], GL_R32UI, node_buffers_[0]);
  // A quarter more nodes than pixels: a draw that covers the target makes
  // a few more fragments than pixels (its triangles share pixels along
  // their edges), and a draw that overflows is drawn again.
  uint64_t first = std::max<uint64_t>(65536, pixels + pixels / 4);
  // Test hooks: the first store and the largest, in nodes (a draw's
  // overflow, its growth and the limit, on small frames).
  if (const uint64_t n = env_nodes("ROPSIM_TEST_GL_NODES")) first = n;
  if (const uint64_t n = env_nodes("ROPSIM_TEST_GL_MAX_NODES")) max_nodes_ = std::min(max_nodes_, (n + 63) / 64 * 64);
  reserve_nodes(first);
  g.GenQueries(1, &query_);
  g.GenQueries(1, &kept_query_);
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

bool Session::node_store(int b, uint64_t bytes) {
  const GlFunctions& g = real_gl();
  const GLuint buffer = node_buffers_[size_t(b)];
  if (pinned_) {
    // The store it replaces may still be in use by the passes drawn: its
    // memory is released only after they end.
    if (node_memory_[size_t(b)].size()) g.Finish();
    LargeArray<uint8_t> memory(bytes);
    g.BindBuffer(GL_EXTERNAL_VIRTUAL_MEMORY_BUFFER_AMD, buffer);
    g.BufferData(GL_EXTERNAL_VIRTUAL_MEMORY_BUFFER_AMD, GLsizeiptr(bytes), memory.data(), GL_DYNAMIC_READ);
    g.BindBuffer(GL_EXTERNAL_VIRTUAL_MEMORY_BUFFER_AMD, 0);
    GLint64 size = 0;
    g.GetNamedBufferParameteri64v(buffer, GL_BUFFER_SIZE, &size);
    if (uint64_t(size) == bytes) {
      node_memory_[size_t(b)] = std::move(memory);
      return true;
    }
    pinned_ = false;  // refused: the driver's own stores from here on
  }
  g.NamedBufferData(buffer, GLsizeiptr(bytes), nullptr, GL_DYNAMIC_READ);
  return false;
}

void Session::reserve_nodes(uint64_t nodes) {
  // A multiple of 64 nodes: each sample's depth range starts aligned.
  const GlFunctions& g = real_gl();
  node_capacity_ = std::min<uint64_t>(max_nodes_, (nodes + 63) / 64 * 64);
  for (int b = 1; b <= 3; ++b) node_store(b, node_capacity_ * node_bytes(b));
  g.TextureBuffer(fetch_textures_[1], GL_RGBA32UI, node_buffers_[1]);  // the keys' new store
  depth_capacity_ = 0;                                                 // sized by the draw's spp at its first pass
}

void Session::bind_nodes(int sample) {
  const GlFunctions& g = real_gl();
  g.BindBufferRange(GL_SHADER_STORAGE_BUFFER, GLuint(binding_), node_buffers_[0], 0, GLsizeiptr(heads_bytes()));
  for (int b = 1; b <= 3; ++b)
    g.BindBufferRange(GL_SHADER_STORAGE_BUFFER, GLuint(binding_ + b), node_buffers_[size_t(b)], 0,
                      GLsizeiptr(node_capacity_ * node_bytes(b)));
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
  g.NamedRenderbufferStorage(rb, GL_STENCIL_INDEX8, target_.width, target_.height);
  g.NamedFramebufferRenderbuffer(capture_fbo_, GL_STENCIL_ATTACHMENT, GL_RENDERBUFFER, rb);
  if (g.CheckNamedFramebufferStatus(capture_fbo_, GL_DRAW_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    fail("the capture framebuffer with its " + std::to_string(target_.width) + "x" + std::to_string(target_.height) +
         " stencil buffer is not complete");
}

void Session::split_pass(const ProgramSet& set, int s, std::array<float, 2> off, std::array<float, 2> pixel_off,
                         const std::vector<DrawCallPart>& parts, bool query) {
  const GlFunctions& g = real_gl();
  // The coverage pass: a fragment without a node (the coverage twin keeps
  // it) counts itself in its pixel's stencil.
  const GLint zero = 0;
  // Under the application's scissor, as the passes: outside it no fragment reads the stencil.
  g.ClearNamedFramebufferiv(capture_fbo_, GL_STENCIL, 0, &zero);
  const Instrumented& cov = set.coverage;
  g.UseProgram(cov.program);
  g.ProgramUniform2f(cov.program, cov.loc_offset, off[0], off[1]);
  g.Enable(GL_STENCIL_TEST);
  g.StencilFuncSeparate(GL_FRONT_AND_BACK, GL_ALWAYS, 0, 0xFF);
  g.StencilOpSeparate(GL_FRONT_AND_BACK, GL_KEEP, GL_KEEP, GL_INCR);
  // Whether it keeps any fragment: the shading pass is drawn only then.
  if (query) g.BeginQuery(GL_ANY_SAMPLES_PASSED, kept_query_);
  for (size_t k = 0; k < parts.size(); ++k) {
    if (cov.loc_part >= 0) g.ProgramUniform1ui(cov.program, cov.loc_part, GLuint(k));
    parts[k].replay();
  }
  if (query) g.EndQuery(GL_ANY_SAMPLES_PASSED);
  g.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);  // the coverage pass's depths before the shading pass
  // The shading pass, tested before the shader: every fragment of a pixel
  // where one or more have no node (those make theirs and shade; the others
  // find theirs and shade nothing).
  const Instrumented& sh = set.shading;
  g.UseProgram(sh.program);
  g.ProgramUniform2f(sh.program, sh.loc_offset, off[0], off[1]);
  if (sh.loc_pixel_offset >= 0) g.ProgramUniform2f(sh.program, sh.loc_pixel_offset, pixel_off[0], pixel_off[1]);
  g.ProgramUniform1i(sh.program, sh.loc_pass, int(PassKind::kSample));
  if (sh.loc_sample >= 0) g.ProgramUniform1ui(sh.program, sh.loc_sample, GLuint(s));
  g.StencilOpSeparate(GL_FRONT_AND_BACK, GL_KEEP, GL_KEEP, GL_KEEP);
  g.StencilFuncSeparate(GL_FRONT_AND_BACK, GL_LEQUAL, 1, 0xFF);  // 1 <= stencil
  if (query) g.BeginConditionalRender(kept_query_, GL_QUERY_WAIT);
  for (size_t k = 0; k < parts.size(); ++k) {
    if (sh.loc_part >= 0) g.ProgramUniform1ui(sh.program, sh.loc_part, GLuint(k));
    parts[k].replay();
  }
  if (query) g.EndConditionalRender();
  g.Disable(GL_STENCIL_TEST);
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
  // An occlusion query of the application's own would count the passes
  // (and no other may start while it runs).
  GLint app_query = 0, app_any = 0, app_conservative = 0;
  g.GetQueryiv(GL_SAMPLES_PASSED, GL_CURRENT_QUERY, &app_query);
  g.GetQueryiv(GL_ANY_SAMPLES_PASSED, GL_CURRENT_QUERY, &app_any);
  g.GetQueryiv(GL_ANY_SAMPLES_PASSED_CONSERVATIVE, GL_CURRENT_QUERY, &app_conservative);
  const bool count = count_samples_ && app_query == 0;
  // The shading passes' conditional rendering: not inside the application's own.
  const bool kept_query = app_query == 0 && app_any == 0 && app_conservative == 0 && !application_conditional_render();
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
      // A new store: zero (kNoDepth) where it is fresh pinned memory, else undefined.
      depth_dirty_ = node_store(4, depth_capacity_ * 4) ? 0 : node_capacity_;
    }
    g.MemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);  // the previous draw's nodes read before the reset
    const uint32_t empty = kNoNode;
    g.ClearNamedBufferData(node_buffers_[0], GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &empty);
    const uint32_t zero[kHeadsHeaderWords] = {};
    g.NamedBufferSubData(node_buffers_[0], 0, sizeof zero, zero);
    // Every sample uncovered until a pass writes its depth: in each
    // sample's range, the nodes an earlier draw's passes wrote (the passes
    // write the depths of nodes below the capacity only).
    for (int s = 0; s < spp_ && depth_dirty_ > 0; ++s)
      g.ClearNamedBufferSubData(node_buffers_[4], GL_R32UI, GLintptr(uint64_t(s) * node_capacity_ * 4),
                                GLsizeiptr(depth_dirty_ * 4), GL_RED_INTEGER, GL_UNSIGNED_INT, &kNoDepth);
    depth_dirty_ = 0;
    for (const Instrumented* p : {&ins, &set.shading, &set.coverage}) {
      if (!p->program || (p != &ins && !split)) continue;
      if (p->loc_capacity >= 0) g.ProgramUniform1ui(p->program, p->loc_capacity, GLuint(node_capacity_));
      if (p->loc_width >= 0) g.ProgramUniform1ui(p->program, p->loc_width, GLuint(target_.width));
      if (p->loc_lists >= 0) g.ProgramUniform1ui(p->program, p->loc_lists, GLuint(lists_));
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
        split_pass(set, s, off, pixel_off, parts, kept_query);
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
    depth_dirty_ = std::min<uint64_t>(made, node_capacity_);
    if (made <= node_capacity_) break;
    // Past the capacity a fragment finds no node of its own in the next
    // pass and counts again, so `made` is at least the draw's fragments,
    // not their number: only a draw that overflows the largest store fails.
    if (node_capacity_ >= max_nodes_)
      fail("draw " + std::to_string(d.index) + " (" + d.name + "): it makes more fragments than the " +
           std::to_string(max_nodes_) + " nodes a storage block holds (GL_MAX_SHADER_STORAGE_BLOCK_SIZE)");
    reserve_nodes(made + made / 8);  // at most max_nodes_; and the draw's passes again
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
      mapped[size_t(b)] =
          g.MapNamedBufferRange(node_buffers_[size_t(b)], 0, GLsizeiptr(made * node_bytes(b)), GL_MAP_READ_BIT);
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
  EncodedDraw draw;
  const bool clamp = target_.encoding != TargetEncoding::kFloat;
  const TraceHeader layout = trace_layout();
  // The records go into the trace as they are encoded (framed, checksummed
  // and compressed by zstd's threads while the next run is encoded); a list
  // only counts them.
  TraceWriter* trace_writer = list_only_ ? nullptr : &trace();
  const RecordSink sink = [&](const uint8_t* records, size_t bytes, size_t count) {
    if (!trace_writer) return std::string();
    try {
      trace_writer->write_records(records, bytes, count);
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  t = std::chrono::steady_clock::now();
  const std::string err = made ? build_records(nodes, d.trace_id, shape, clamp, layout, scratch_, sink, draw) : "";
  if (made)
    for (int b = 1; b <= 4; ++b) g.UnmapNamedBuffer(node_buffers_[size_t(b)]);
  if (!err.empty()) fail(err);
  times_s_.build += seconds_since(t);
  d.fragments = draw.count;
  d.covered_samples = draw.covered_samples;
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

}  // namespace ropsim::glcapture
