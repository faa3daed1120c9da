#include "traces/glcapture/instrumented_program.h"

#include <algorithm>
#include <cstring>

#include "traces/glcapture/gl_functions.h"
#include "traces/glcapture/glsl_rewrite.h"

namespace ropsim::glcapture {

UniformShape uniform_shape(GLenum type) {
  switch (type) {
    case GL_FLOAT:
      return {'f', 1, 0};
    case GL_FLOAT_VEC2:
      return {'f', 2, 0};
    case GL_FLOAT_VEC3:
      return {'f', 3, 0};
    case GL_FLOAT_VEC4:
      return {'f', 4, 0};
    case GL_INT:
    case GL_BOOL:
      return {'i', 1, 0};
    case GL_INT_VEC2:
    case GL_BOOL_VEC2:
      return {'i', 2, 0};
    case GL_INT_VEC3:
    case GL_BOOL_VEC3:
      return {'i', 3, 0};
    case GL_INT_VEC4:
    case GL_BOOL_VEC4:
      return {'i', 4, 0};
    case GL_UNSIGNED_INT:
      return {'u', 1, 0};
    case GL_UNSIGNED_INT_VEC2:
      return {'u', 2, 0};
    case GL_UNSIGNED_INT_VEC3:
      return {'u', 3, 0};
    case GL_UNSIGNED_INT_VEC4:
      return {'u', 4, 0};
    case GL_DOUBLE:
      return {'d', 1, 0};
    case GL_DOUBLE_VEC2:
      return {'d', 2, 0};
    case GL_DOUBLE_VEC3:
      return {'d', 3, 0};
    case GL_DOUBLE_VEC4:
      return {'d', 4, 0};
    case GL_FLOAT_MAT2:
      return {'m', 2, 2};
    case GL_FLOAT_MAT3:
      return {'m', 3, 3};
    case GL_FLOAT_MAT4:
      return {'m', 4, 4};
    case GL_FLOAT_MAT2x3:
      return {'m', 2, 3};
    case GL_FLOAT_MAT2x4:
      return {'m', 2, 4};
    case GL_FLOAT_MAT3x2:
      return {'m', 3, 2};
    case GL_FLOAT_MAT3x4:
      return {'m', 3, 4};
    case GL_FLOAT_MAT4x2:
      return {'m', 4, 2};
    case GL_FLOAT_MAT4x3:
      return {'m', 4, 3};
    case GL_UNSIGNED_INT_ATOMIC_COUNTER:
      return {'-', 0, 0};  // has no value of its own
    default:
      return {'i', 1, 0};  // samplers and images: a unit
  }
}

namespace {

/// One attempt at the instrumented program, with the inputs in as_is read as
/// the shader reads them; unmatched: the input a failed link names, if any.
void build_once(GLuint program, const std::vector<ShaderSource>& src, const std::string& who, GLint binding,
                ProgramVariant variant, GLint unit, const std::vector<std::string>& as_is, Instrumented& ins,
                std::string& unmatched) {
  const GlFunctions& g = real_gl();
  std::string log;
  // The coverage variant: the application's vertex shaders and one fragment
  // shader of the capture's own in place of the application's.
  std::vector<ShaderSource> sources;
  for (const ShaderSource& s : src)
    if (variant != ProgramVariant::kCoverage || s.type == GL_VERTEX_SHADER) sources.push_back(s);
  if (variant == ProgramVariant::kCoverage) sources.push_back({GL_FRAGMENT_SHADER, ""});
  for (GlslProfile profile : {GlslProfile::kCompatibility, GlslProfile::kCore}) {
    std::vector<GLuint> shaders;
    bool ok = true;
    for (const ShaderSource& s : sources) {
      const Rewritten r =
          s.type == GL_VERTEX_SHADER ? instrument_vertex_shader(s.source, profile)
          : variant == ProgramVariant::kCoverage
              ? coverage_fragment_shader(profile, binding, unit)
              : instrument_fragment_shader(s.source, profile, binding, as_is, variant == ProgramVariant::kShading);
      if (!r.error.empty()) {
        ins.error = who + ": " + r.error;
        for (GLuint sh : shaders) g.DeleteShader(sh);
        return;
      }
      const GLuint sh = g.CreateShader(s.type);
      const char* text = r.source.c_str();
      g.ShaderSource(sh, 1, &text, nullptr);
      g.CompileShader(sh);
      shaders.push_back(sh);
      GLint compiled = 0;
      g.GetShaderiv(sh, GL_COMPILE_STATUS, &compiled);
      if (!compiled) {
        char buf[4096] = {};
        g.GetShaderInfoLog(sh, sizeof buf, nullptr, buf);
        // The first error line of the log (warnings come before it), else the log.
        std::string reason = buf;
        const size_t e = reason.find("error:");
        if (e != std::string::npos) {
          const size_t from = reason.rfind('\n', e), to = reason.find('\n', e);
          reason = reason.substr(
              from == std::string::npos ? 0 : from + 1,
              to == std::string::npos ? std::string::npos : to - (from == std::string::npos ? 0 : from + 1));
        }
        while (!reason.empty() && (reason.back() == '\n' || reason.back() == ' ')) reason.pop_back();
        // The first profile's reason (compatibility: every source's first
        // try), and the core profile's where it says something else (a
        // source that only compiles as core fails there for its own reason).
        if (log.empty())
          log = std::string("the instrumented ") + (s.type == GL_VERTEX_SHADER ? "vertex" : "fragment") +
                " shader does not compile: " + reason;
        else if (log.find(reason) == std::string::npos)
          log += "; as GLSL 4.50 core: " + reason;
        ok = false;
        break;
      }
    }
    if (ok) {
      const GLuint q = g.CreateProgram();
      for (GLuint sh : shaders) g.AttachShader(q, sh);
      // The application's attribute locations (bound or assigned at its link).
      GLint attribs = 0;
      if (program) g.GetProgramiv(program, GL_ACTIVE_ATTRIBUTES, &attribs);
      for (GLint i = 0; i < attribs; ++i) {
        char name[256] = {};
        GLint size = 0;
        GLenum type = 0;
        g.GetActiveAttrib(program, GLuint(i), sizeof name, nullptr, &size, &type, name);
        const GLint loc = g.GetAttribLocation(program, name);
        if (loc >= 0 && std::strncmp(name, "gl_", 3) != 0) g.BindAttribLocation(q, GLuint(loc), name);
      }
      g.LinkProgram(q);
      GLint linked = 0;
      g.GetProgramiv(q, GL_LINK_STATUS, &linked);
      if (linked) {
        ins.program = q;
      } else {
        char buf[1024] = {};
        g.GetProgramInfoLog(q, sizeof buf, nullptr, buf);
        log = std::string("the instrumented program does not link: ") + buf;
        // Mesa: "fragment shader input `NAME' has no matching output in the previous stage".
        const std::string text = buf;
        const size_t a = text.find("input `"), b = a == std::string::npos ? a : text.find('\'', a + 7);
        if (b != std::string::npos && text.find("no matching output") != std::string::npos)
          unmatched = text.substr(a + 7, b - a - 7);
        g.DeleteProgram(q);
      }
    }
    for (GLuint sh : shaders) g.DeleteShader(sh);
    if (ins.program) break;
  }
  if (!ins.program) {
    std::string line = log.substr(0, log.find('\n'));
    ins.error = who + ": " + line;
    return;
  }
  const GLuint q = ins.program;
  ins.loc_offset = g.GetUniformLocation(q, "ropsim_offset");
  ins.loc_capacity = g.GetUniformLocation(q, "ropsim_capacity");
  ins.loc_upside_down = g.GetUniformLocation(q, "ropsim_upside_down");
  ins.loc_pixel_offset = g.GetUniformLocation(q, "ropsim_pixel_offset");
  ins.loc_alpha_func = g.GetUniformLocation(q, "ropsim_alpha_func");
  ins.loc_alpha_ref = g.GetUniformLocation(q, "ropsim_alpha_ref");
  ins.loc_alpha_one = g.GetUniformLocation(q, "ropsim_alpha_one");
  ins.loc_pass = g.GetUniformLocation(q, "ropsim_pass");
  ins.loc_sample = g.GetUniformLocation(q, "ropsim_sample");
  ins.loc_gate = g.GetUniformLocation(q, "ropsim_gate");
  ins.loc_part = g.GetUniformLocation(q, "ropsim_part");
  ins.loc_width = g.GetUniformLocation(q, "ropsim_width");
  ins.loc_lists = g.GetUniformLocation(q, "ropsim_lists");
  if (variant == ProgramVariant::kCoverage
          ? ins.loc_offset < 0 || ins.loc_upside_down < 0 || ins.loc_width < 0 || ins.loc_lists < 0
          : ins.loc_capacity < 0 || ins.loc_offset < 0 || ins.loc_upside_down < 0 || ins.loc_pass < 0 ||
                ins.loc_lists < 0) {
    ins.error = who + ": the instrumented program lacks the capture's uniforms";
    return;
  }
  if (program == 0) return;  // fixed function: built-ins and sampler bindings only
  GLint uniforms = 0;
  g.GetProgramiv(program, GL_ACTIVE_UNIFORMS, &uniforms);
  for (GLint i = 0; i < uniforms; ++i) {
    char name[512] = {};
    GLint size = 0, block = -1;
    GLenum type = 0;
    g.GetActiveUniform(program, GLuint(i), sizeof name, nullptr, &size, &type, name);
    const GLuint ui = GLuint(i);
    g.GetActiveUniformsiv(program, 1, &ui, GL_UNIFORM_BLOCK_INDEX, &block);
    if (block != -1 || std::strncmp(name, "gl_", 3) == 0) continue;
    const UniformShape shape = uniform_shape(type);
    if (shape.kind == '-') continue;
    std::string base = name;
    const bool array = base.size() > 3 && base.compare(base.size() - 3, 3, "[0]") == 0;
    if (array) base.resize(base.size() - 3);
    for (GLint k = 0; k < std::max(1, size); ++k) {
      const std::string element = array ? base + "[" + std::to_string(k) + "]" : base;
      const GLint from = g.GetUniformLocation(program, element.c_str()), to = g.GetUniformLocation(q, element.c_str());
      if (from >= 0 && to >= 0) ins.uniforms.push_back({shape, from, to});
    }
  }
  GLint blocks = 0;
  g.GetProgramiv(program, GL_ACTIVE_UNIFORM_BLOCKS, &blocks);
  for (GLint i = 0; i < blocks; ++i) {
    char name[256] = {};
    g.GetActiveUniformBlockName(program, GLuint(i), sizeof name, nullptr, name);
    const GLuint j = g.GetUniformBlockIndex(q, name);
    if (j != GL_INVALID_INDEX) ins.uniform_blocks.push_back({GLuint(i), j});
  }
  GLint storage = 0;
  g.GetProgramInterfaceiv(program, GL_SHADER_STORAGE_BLOCK, GL_ACTIVE_RESOURCES, &storage);
  for (GLint i = 0; i < storage; ++i) {
    char name[256] = {};
    g.GetProgramResourceName(program, GL_SHADER_STORAGE_BLOCK, GLuint(i), sizeof name, nullptr, name);
    const GLuint j = g.GetProgramResourceIndex(q, GL_SHADER_STORAGE_BLOCK, name);
    if (j != GL_INVALID_INDEX) ins.storage_blocks.push_back({GLuint(i), j});
  }
}

}  // namespace

void build_instrumented(GLuint program, const std::vector<ShaderSource>& src, const std::string& who, GLint binding,
                        Instrumented& ins, ProgramVariant variant, GLint unit) {
  bool vertex = false, fragment = false;
  for (const ShaderSource& s : src) {
    if (s.type == GL_VERTEX_SHADER)
      vertex = true;
    else if (s.type == GL_FRAGMENT_SHADER)
      fragment = true;
    else {
      ins.error = who + ": its " +
                  std::string(s.type == GL_GEOMETRY_SHADER  ? "geometry"
                              : s.type == GL_COMPUTE_SHADER ? "compute"
                                                            : "tessellation") +
                  " shader cannot be instrumented (vertex and fragment shaders only)";
      return;
    }
  }
  if (!vertex || !fragment) {
    ins.error = who + (src.empty() ? ": its shader sources are unknown (no shader attached when it was linked)"
                                   : ": it has no " + std::string(vertex ? "fragment" : "vertex") +
                                         " shader (the capture instruments both)");
    return;
  }
  // An input the fragment shader names only under a preprocessor branch it
  // does not compile (OpenArena's var_ColorAmbient) and that the vertex
  // shader does not write: the wrapper's centre read makes it used, and the
  // link fails naming it; it is then read as the shader reads it, and the
  // program built again.
  std::vector<std::string> as_is;
  for (;;) {
    std::string unmatched;
    build_once(program, src, who, binding, variant, unit, as_is, ins, unmatched);
    if (ins.program || unmatched.empty() || std::find(as_is.begin(), as_is.end(), unmatched) != as_is.end() ||
        as_is.size() >= 32)
      break;
    as_is.push_back(unmatched);
    ins.error.clear();
  }
}

void copy_uniforms(GLuint program, const Instrumented& ins) {
  if (program == 0) return;
  const GlFunctions& g = real_gl();
  const GLuint q = ins.program;
  for (const UniformCopy& u : ins.uniforms) {
    const UniformShape& s = u.shape;
    switch (s.kind) {
      case 'f': {
        GLfloat v[4] = {};
        g.GetUniformfv(program, u.from, v);
        (s.n == 1   ? g.ProgramUniform1fv
         : s.n == 2 ? g.ProgramUniform2fv
         : s.n == 3 ? g.ProgramUniform3fv
                    : g.ProgramUniform4fv)(q, u.to, 1, v);
        break;
      }
      case 'i': {
        GLint v[4] = {};
        g.GetUniformiv(program, u.from, v);
        (s.n == 1   ? g.ProgramUniform1iv
         : s.n == 2 ? g.ProgramUniform2iv
         : s.n == 3 ? g.ProgramUniform3iv
                    : g.ProgramUniform4iv)(q, u.to, 1, v);
        break;
      }
      case 'u': {
        GLuint v[4] = {};
        g.GetUniformuiv(program, u.from, v);
        (s.n == 1   ? g.ProgramUniform1uiv
         : s.n == 2 ? g.ProgramUniform2uiv
         : s.n == 3 ? g.ProgramUniform3uiv
                    : g.ProgramUniform4uiv)(q, u.to, 1, v);
        break;
      }
      case 'd': {
        GLdouble v[4] = {};
        g.GetUniformdv(program, u.from, v);
        (s.n == 1   ? g.ProgramUniform1dv
         : s.n == 2 ? g.ProgramUniform2dv
         : s.n == 3 ? g.ProgramUniform3dv
                    : g.ProgramUniform4dv)(q, u.to, 1, v);
        break;
      }
      case 'm': {
        GLfloat v[16] = {};
        g.GetUniformfv(program, u.from, v);
        PFNGLPROGRAMUNIFORMMATRIX4FVPROC set = nullptr;
        if (s.n == s.rows)
          set = s.n == 2 ? g.ProgramUniformMatrix2fv : s.n == 3 ? g.ProgramUniformMatrix3fv : g.ProgramUniformMatrix4fv;
        else if (s.n == 2)
          set = s.rows == 3 ? g.ProgramUniformMatrix2x3fv : g.ProgramUniformMatrix2x4fv;
        else if (s.n == 3)
          set = s.rows == 2 ? g.ProgramUniformMatrix3x2fv : g.ProgramUniformMatrix3x4fv;
        else
          set = s.rows == 2 ? g.ProgramUniformMatrix4x2fv : g.ProgramUniformMatrix4x3fv;
        set(q, u.to, 1, GL_FALSE, v);
        break;
      }
      default:
        break;
    }
  }
  for (const auto& b : ins.uniform_blocks) {
    GLint binding = 0;
    g.GetActiveUniformBlockiv(program, b.first, GL_UNIFORM_BLOCK_BINDING, &binding);
    g.UniformBlockBinding(q, b.second, GLuint(binding));
  }
  for (const auto& b : ins.storage_blocks) {
    const GLenum prop = GL_BUFFER_BINDING;
    GLint binding = 0;
    g.GetProgramResourceiv(program, GL_SHADER_STORAGE_BLOCK, b.first, 1, &prop, 1, nullptr, &binding);
    g.ShaderStorageBlockBinding(q, b.second, GLuint(binding));
  }
}

}  // namespace ropsim::glcapture
