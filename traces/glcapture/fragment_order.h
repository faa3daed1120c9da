// The GL capture's plain-C++ rules (docs/capture.md "Capturing a GL frame"):
// the per-pass sample offset, and the fragments of a draw rebuilt in API order
// from the records its passes appended. No GL calls here, so the rules are
// tested without a context.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "traces/format/trace.h"

namespace ropsim::glcapture {

/// The clip-space offset (per unit w, i.e. in normalised device coordinates)
/// that moves the geometry so that the pixel centre samples where sample `p`
/// lies: the geometry moves by minus the sample's offset from the centre.
/// `p` is in trace coordinates (1/256 pixel from the top-left corner, y
/// down); GL's window y points up. viewport_w/h: glViewport's size.
std::array<float, 2> sample_clip_offset(SamplePos p, int viewport_w, int viewport_h);

/// The pass at the pixel centre (PassRecord::sample): it gives the colour of
/// the fragments whose centre it covers, and no coverage.
inline constexpr int kCentrePass = 64;

/// Whether the capture makes a centre pass at `spp`: unless a sample lies at
/// the centre (1 spp), so that colour is shaded where GL's multisampling
/// shades it.
bool needs_centre_pass(const std::array<SamplePos, 64>& positions, int spp);

/// One record a pass appended (glsl_rewrite.h kRecordWords), decoded.
struct PassRecord {
  uint16_t x = 0, y = 0;  ///< pixel in trace coordinates (row 0 at the top)
  uint32_t prim = 0;      ///< gl_PrimitiveID
  uint32_t instance = 0;  ///< gl_InstanceID
  uint32_t part = 0;      ///< the sub-draw (glMultiDraw*), 0 otherwise
  uint8_t sample = 0;     ///< the pass: the sample position it samples, or kCentrePass
  float z = 0;            ///< gl_FragCoord.z
  std::array<float, 4> rgba{};
};

/// Decodes `count` raw records of one pass; gl window y becomes trace row
/// height - 1 - y. Records whose pixel is outside width x height are
/// refused (returns the reason), as is a depth outside [0, 1].
std::string decode_records(const uint32_t* raw, size_t count, uint32_t width, uint32_t height, uint32_t part,
                           int sample, std::vector<PassRecord>& out);

/// A draw's part: how many primitives one instance of it has, when the call
/// says (0: unknown, taken from the records).
struct DrawPart {
  uint32_t prims_per_instance = 0;
};

/// A fragment kept until the frame ends (its draw states go into the header
/// first): the per-sample depths of its covered samples, in sample order.
struct CapturedFragment {
  uint32_t draw_id = 0, prim_id = 0;
  uint16_t x = 0, y = 0;
  uint64_t coverage = 0;
  std::array<float, 4> rgba{};
  std::vector<float> z;  ///< one per covered sample, lowest sample first
};

/// The fragments of one draw in API order: by part, then instance, then
/// primitive (prim_id = the parts' primitives before it + instance *
/// primitives per instance + gl_PrimitiveID), then row, then column. Every
/// sample pass contributes its sample's coverage bit and depth; the colour is
/// the centre pass's where it covers the pixel, else the lowest covered
/// sample's (a centre the primitive misses is not shaded). A primitive and
/// pixel with a centre record but no covered sample makes no fragment. clamp: colour and alpha clamped to
/// [0, 1] (unorm and sRGB targets); otherwise alpha is clamped to [0, 1]
/// and colour to >= 0 (what a trace holds). The result does not depend on
/// the records' order (a record that repeats a
/// (part, instance, primitive, pixel, sample) keeps the smallest depth, then
/// colour, bit for bit). width x height: the target (0 x 0: the records'
/// extent). Returns "" or why the ids overflow 32 bits (or a record lies
/// outside the target).
std::string build_fragments(const std::vector<PassRecord>& records, uint32_t draw_id,
                            const std::vector<DrawPart>& parts, bool clamp, std::vector<CapturedFragment>& out,
                            uint32_t width = 0, uint32_t height = 0);

/// A CapturedFragment as the trace's Fragment (DepthMode::kPerSample).
Fragment to_trace_fragment(const CapturedFragment& f);

}  // namespace ropsim::glcapture
