// An application program's instrumented twin (docs/capture.md "One draw"):
// the rewritten shaders compiled and linked with the application program's
// attribute locations, and the lists that copy its uniform values and block
// bindings before each re-execution. GL calls through real_gl() only.
#pragma once
#include <GL/gl.h>

#include <string>
#include <utility>
#include <vector>

namespace ropsim::glcapture {

/// How a uniform's value is read and written: kind and shape.
struct UniformShape {
  char kind;  ///< 'f', 'i', 'u', 'd', 'm' (float matrix)
  int n;      ///< components (vectors) or columns (matrices)
  int rows;   ///< matrix rows
};

/// The shape of a uniform of GL type `type` (samplers and images: an int unit).
UniformShape uniform_shape(GLenum type);

struct UniformCopy {
  UniformShape shape;
  GLint from = -1, to = -1;  ///< locations in the application's program and in the instrumented one
};

/// An application program's instrumented twin.
struct Instrumented {
  GLuint program = 0;
  std::string error;  ///< "" or why it cannot be made ("program N: ...")
  GLint loc_offset = -1, loc_capacity = -1, loc_upside_down = -1;
  /// ropsim_pass (PassKind), ropsim_sample, ropsim_gate, ropsim_part,
  /// ropsim_width (the target's) and ropsim_lists (lists a pixel): a
  /// fragment's list head (glsl_rewrite.cpp).
  GLint loc_pass = -1, loc_sample = -1, loc_gate = -1, loc_part = -1, loc_width = -1, loc_lists = -1;
  /// ropsim_pixel_offset, the pass's geometry shift in pixels (window
  /// coordinates); -1 when the fragment shader has no interpolated input.
  GLint loc_pixel_offset = -1;
  /// ropsim_alpha_func, ropsim_alpha_ref, ropsim_alpha_one: the alpha test
  /// the wrapper applies (glsl_rewrite.cpp); -1 where the program has none.
  GLint loc_alpha_func = -1, loc_alpha_ref = -1, loc_alpha_one = -1;
  std::vector<UniformCopy> uniforms;
  std::vector<std::pair<GLuint, GLuint>> uniform_blocks, storage_blocks;  ///< (application's, ours)
};

struct ShaderSource {
  GLenum type;
  std::string source;
};

/// Which instrumented twin (docs/capture.md "One draw"): the wrapper of the
/// application's fragment shader (the centre pass, the passes counted by
/// GL_SAMPLES_PASSED, the 4x reference); the same with the fragment tests
/// before the shader (the stencil-culled shading passes); or the
/// application's vertex shader with the capture's coverage fragment shader
/// (the sample passes: glsl_rewrite.h coverage_fragment_shader()).
enum class ProgramVariant { kPlain, kShading, kCoverage };

/// Builds `ins` for `program` (0: a fixed-function equivalent, no uniforms
/// to copy) from its shader sources; the fragment nodes go to storage
/// bindings `binding` .. `binding` + kCaptureBindings - 1. On failure `ins.error` says why, naming `who`.
/// `unit`: the coverage variant's two texture units (glsl_rewrite.h
/// coverage_fragment_shader()).
void build_instrumented(GLuint program, const std::vector<ShaderSource>& src, const std::string& who, GLint binding,
                        Instrumented& ins, ProgramVariant variant = ProgramVariant::kPlain, GLint unit = 0);

/// An application program's instrumented twins: the plain one, built at its
/// first captured draw (its error is the draw's), and the shading and
/// coverage ones, built when a draw is first captured above 1 spp (when
/// either fails, the passes use the plain one alone, as at 1 spp).
struct ProgramSet {
  Instrumented plain, shading, coverage;
  bool split_tried = false;
  bool split() const { return shading.program && coverage.program && shading.error.empty() && coverage.error.empty(); }
};

/// Copies the application program's uniform values and block bindings to
/// its instrumented twin (nothing for program 0).
void copy_uniforms(GLuint program, const Instrumented& ins);

}  // namespace ropsim::glcapture
