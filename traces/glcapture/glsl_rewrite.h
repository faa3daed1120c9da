// The shader rewrite of the GL capture (docs/capture.md "Capturing a GL
// frame"): an application's vertex and fragment shader sources become the
// instrumented pair that re-executes a draw, one pass per sample position,
// and appends every fragment that survives the fragment shader to a shader
// storage buffer. Plain text in, plain text out: no GL calls here.
#pragma once
#include <string>
#include <vector>

namespace ropsim::glcapture {

/// The GLSL profile the instrumented shaders declare: `compatibility` keeps
/// gl_FragColor, texture2D, attribute and varying (GLSL 1.10 .. 4.60 and
/// GLSL ES sources); `core` serves core-profile contexts.
enum class GlslProfile { kCompatibility, kCore };

/// 32-bit words per fragment record in the storage buffer: the pixel (x | y
/// << 16, GL window coordinates), gl_PrimitiveID, the instance, gl_FragCoord.z
/// (float bits), and the colour's r, g, b, a (float bits).
inline constexpr unsigned kRecordWords = 8;
/// Words before the records: the atomic count and three pad words (the
/// records are two uvec4 each, 16-byte aligned in std430).
inline constexpr unsigned kRecordHeaderWords = 4;

struct Rewritten {
  std::string source;  ///< empty when error is set
  std::string error;   ///< "" or why the source cannot be instrumented
};

/// The source without its comments (each replaced by one space, newlines
/// kept, so line numbers in compile logs stay the application's).
std::string strip_comments(const std::string& src);

/// The vertex shader: its `main` renamed, and a new `main` after it that
/// calls it, passes gl_InstanceID to the fragment shader (flat) and moves
/// gl_Position by `ropsim_offset` (a uniform vec2, in normalised device
/// coordinates, scaled by w); with the uniform bool `ropsim_upside_down` it
/// also negates gl_Position.y (the 4x reference, drawn upside down so that
/// GL's sample positions fall where the trace header's are). A shader object
/// without `main` only has its #version replaced.
Rewritten instrument_vertex_shader(const std::string& src, GlslProfile profile);

/// The colour the fragment shader writes, as a GLSL expression read after
/// its main returns: the `out vec4` at location 0 (or the only one),
/// gl_FragData[0], gl_FragColor, or opaque black when it writes none.
std::string fragment_color_expression(const std::string& stripped_src);

/// The fragment shader: its `main` renamed, and a new `main` that calls it
/// and then appends one record (kRecordWords) to the buffer at `binding`
/// (block RopsimFragments; uniform `ropsim_capacity` bounds the records
/// written, the count goes on past it so that an overflow is seen). An
/// invocation that discards appends nothing; helper invocations append
/// nothing.
/// as_is: inputs not to read at the pixel centre (the library's retry for an
/// input whose centre read fails to link: see instrumented_program.cpp).
Rewritten instrument_fragment_shader(const std::string& src, GlslProfile profile, int binding,
                                     const std::vector<std::string>& as_is = {});

}  // namespace ropsim::glcapture
