// The shader rewrite of the GL capture (docs/capture.md "Capturing a GL
// frame"): an application's vertex and fragment shader sources become the
// instrumented pair that re-executes a draw, one pass per sample position,
// and gathers each fragment (coverage, depths, colour) into one node of one
// of its pixel's lists in shader storage buffers. Plain text in, plain text
// out: no GL calls here.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace ropsim::glcapture {

/// The GLSL profile the instrumented shaders declare: `compatibility` keeps
/// gl_FragColor, texture2D, attribute and varying (GLSL 1.10 .. 4.60 and
/// GLSL ES sources); `core` serves core-profile contexts.
enum class GlslProfile { kCompatibility, kCore };

/// The storage bindings the instrumented fragment shader uses, from the
/// `binding` given to instrument_fragment_shader() on: the pixels' list heads
/// (after the node count and three pad words; uniform `ropsim_lists` heads a
/// pixel, a power of two: a fragment's list is the pixel's
/// (gl_PrimitiveID + instance + part) mod ropsim_lists), the nodes' keys (uvec4:
/// gl_PrimitiveID, instance, part, next node), their state (one word: pixel
/// x | y << 16 in GL window coordinates, kNodePixel, and the flags), their
/// colour (vec4), and one pass's depths (a depth word per node: a float's
/// bits inverted, kNoDepth where the fragment does not cover the sample: the
/// depths are the coverage; each sample pass binds its own range).
inline constexpr int kCaptureBindings = 5;
/// Words before the list heads: the node count and three pad words.
inline constexpr unsigned kHeadsHeaderWords = 4;
/// The pixel list's end, and a node index that is no node.
inline constexpr uint32_t kNoNode = 0xFFFFFFFFu;
/// A node's state word: its pixel's bits (x and y below kMaxScreenSide,
/// 2^15), and the flags in the two bits above x and y: the primitive covers
/// the pixel centre (the centre pass made the node), and the shaded
/// invocation kept the fragment (it did not discard).
inline constexpr uint32_t kNodePixel = 0x7FFF7FFFu;
inline constexpr uint32_t kNodeCentre = 1u << 15, kNodeKept = 1u << 31;
/// A depth word of a sample the fragment does not cover (the depths are
/// cleared to it before a draw's passes, and fresh memory holds it: zero); a
/// pass that covers the sample writes depth_word() of gl_FragCoord.z's bits,
/// their inverse, which is never zero for a depth in [0, 1].
inline constexpr uint32_t kNoDepth = 0;
/// The depth word of a covered sample whose depth has the bits `bits`, and back.
constexpr uint32_t depth_word(uint32_t bits) { return ~bits; }
constexpr uint32_t depth_bits(uint32_t word) { return ~word; }
/// ropsim_pass: what a pass records.
enum class PassKind : int { kNone = 0, kCentre = 1, kSample = 2 };

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

/// The fragment shader: its `main` renamed, and a new `main` that records
/// the fragment in the buffers at `binding` .. `binding` + kCaptureBindings
/// - 1 (uniform `ropsim_capacity` bounds the nodes written; the count goes
/// on past it so that an overflow is seen). The centre pass makes each
/// fragment's node (flag kNodeCentre) and shades it; a sample pass sets
/// its sample's coverage bit and depth in the node (made if the centre pass
/// did not), and shades the fragment only when its primitive misses the
/// pixel centre and the sample is its lowest covered one. A shaded
/// invocation that does not discard stores the colour and kNodeKept; helper
/// invocations record nothing.
/// as_is: inputs not to read at the pixel centre (the library's retry for an
/// input whose centre read fails to link: see instrumented_program.cpp).
/// early_tests: the wrapper declares `layout(early_fragment_tests) in` (the
/// shading passes, culled by the stencil test before the shader runs).
Rewritten instrument_fragment_shader(const std::string& src, GlslProfile profile, int binding,
                                     const std::vector<std::string>& as_is = {}, bool early_tests = false);

/// The sample passes' own fragment shader, linked with the instrumented
/// vertex shader: it finds the fragment's node in its pixel's list and sets
/// sample `ropsim_sample`'s coverage bit and depth there, then discards; a
/// fragment whose node does not exist yet (its primitive misses the pixel
/// centre and every earlier sample) is kept, so that the pass marks its
/// pixel in the stencil buffer, and a shading pass (the wrapper with
/// early_tests, the same shift) makes the node and shades it. It runs none
/// of the application's shader.
/// The list heads and the keys are read through texel fetches: buffer
/// textures (R32UI over the heads' buffer, header included; RGBA32UI over
/// the keys) on texture units `unit` and `unit` + 1.
Rewritten coverage_fragment_shader(GlslProfile profile, int binding, int unit);

}  // namespace ropsim::glcapture
