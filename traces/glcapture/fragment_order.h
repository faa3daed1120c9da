// The GL capture's plain-C++ rules (docs/capture.md "Capturing a GL frame"):
// the per-pass sample offset, and the fragments of a draw in API order from
// the nodes its passes left. No GL calls here, so the rules are
// tested without a context.
#pragma once
#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "traces/format/trace.h"

namespace ropsim::glcapture {

/// The clip-space offset (per unit w, i.e. in normalised device coordinates)
/// that moves the geometry so that the pixel centre samples where sample `p`
/// lies: the geometry moves by minus the sample's offset from the centre.
/// `p` is in trace coordinates (1/256 pixel from the top-left corner, y
/// down); GL's window y points up. viewport_w/h: glViewport's size.
std::array<float, 2> sample_clip_offset(SamplePos p, int viewport_w, int viewport_h);

/// The pass at the pixel centre (in the pass loop, after the sample
/// indices): it shades the fragments whose centre it covers, and gives no
/// coverage.
inline constexpr int kCentrePass = 64;

/// Whether the capture makes a centre pass at `spp`: unless a sample lies at
/// the centre (1 spp), so that colour is shaded where GL's multisampling
/// shades it.
bool needs_centre_pass(const std::array<SamplePos, 64>& positions, int spp);

/// A draw's fragment nodes as its passes left them (glsl_rewrite.h), read in
/// place: node i's key words keys[4i ..] (gl_PrimitiveID, instance, part,
/// next), state word state[i] (pixel x | y << 16 in GL window
/// coordinates and the flags, glsl_rewrite.h), colour colour[4i ..], and sample
/// s's depth word depth[s][i] for s < spp (depth_word() of the float's bits; kNoDepth where the
/// fragment does not cover sample s: the node's coverage).
struct NodeView {
  size_t count = 0;
  int spp = 1;
  const uint32_t* keys = nullptr;
  const uint32_t* state = nullptr;
  const float* colour = nullptr;
  std::array<const uint32_t*, 64> depth{};
};

/// A draw's part: how many primitives one instance of it has, when the call
/// says (0: unknown, taken from the nodes).
struct DrawPart {
  uint32_t prims_per_instance = 0;
};

/// A fragment kept until the frame ends (its draw states go into the header
/// first): its covered samples' depths, lowest sample first, are
/// CapturedDraw::z[z_first ..].
struct CapturedFragment {
  uint32_t draw_id = 0, prim_id = 0;
  uint16_t x = 0, y = 0;
  uint64_t coverage = 0;
  std::array<float, 4> rgba{};
  size_t z_first = 0;
};

/// `bytes` of fresh memory (madvise MADV_HUGEPAGE); throws std::bad_alloc.
void* map_pages(size_t bytes);
void unmap_pages(void* p, size_t bytes);

/// An array of a trivially copyable type in a mapping of its own, not
/// zeroed, on transparent huge pages where the kernel gives them: a frame's
/// fragments and depths are hundreds of MB written once, and fresh small
/// pages' faults and zeroing would cost more than writing them.
template <class T>
class LargeArray {
  static_assert(std::is_trivially_copyable<T>::value, "LargeArray holds trivially copyable values");

 public:
  LargeArray() = default;
  explicit LargeArray(size_t n) : n_(n) {
    if (n) data_ = static_cast<T*>(map_pages(n * sizeof(T)));
  }
  LargeArray(LargeArray&& o) noexcept : data_(o.data_), n_(o.n_) { o.data_ = nullptr, o.n_ = 0; }
  LargeArray& operator=(LargeArray&& o) noexcept {
    std::swap(data_, o.data_);
    std::swap(n_, o.n_);
    return *this;
  }
  ~LargeArray() {
    if (data_) unmap_pages(data_, n_ * sizeof(T));
  }
  /// At least n elements: a new, larger mapping (the contents are not kept) when this one has fewer.
  void ensure(size_t n) {
    if (n_ < n) *this = LargeArray(n);
  }
  size_t size() const { return n_; }
  T* data() { return data_; }
  const T* data() const { return data_; }
  T& operator[](size_t i) { return data_[i]; }
  const T& operator[](size_t i) const { return data_[i]; }
  const T* begin() const { return data_; }
  const T* end() const { return data_ + n_; }

 private:
  T* data_ = nullptr;
  size_t n_ = 0;
};

/// One draw's fragments in API order and their depths.
struct CapturedDraw {
  LargeArray<CapturedFragment> fragments;
  LargeArray<float> z;
};

/// The fragments of one draw in API order: by part, then instance, then
/// primitive (prim_id = the parts' primitives before it + instance *
/// primitives per instance + gl_PrimitiveID), then row, then column; one a
/// node that is kept (kNodeKept) and covers a sample. Its colour is the one
/// shaded invocation's (at the pixel centre where the primitive covers it,
/// else at its lowest covered sample); clamp: colour and alpha clamped to
/// [0, 1] (unorm and sRGB targets); otherwise alpha is clamped to [0, 1] and
/// colour to >= 0 (what a trace holds). The result does not depend on the
/// nodes' order (the order llvmpipe's threads made them in): a node is one
/// (part, instance, primitive, pixel), so the API-order keys are unique.
/// width x height: the target (GL rows flipped into trace rows). `out` is
/// replaced. Returns ""
/// or why a node is out of range (a pixel outside the target, a depth
/// outside [0, 1]) or the ids overflow 32 bits.
std::string build_fragments(const NodeView& nodes, uint32_t draw_id, const std::vector<DrawPart>& parts, bool clamp,
                            uint32_t width, uint32_t height, CapturedDraw& out);

/// One draw's fragments as trace records, in API order.
struct EncodedDraw {
  LargeArray<uint8_t> bytes;  ///< the records back to back (encode_fragment_record())
  size_t size = 0;            ///< bytes of records
  size_t count = 0;           ///< fragments
  size_t covered_samples = 0;
};

/// A fragment's API-order key, (prim_id, row, column), and its node; 12
/// bytes (packed): the sort's two arrays of them are the largest scratch.
struct OrderKey {
  uint64_t order;  ///< prim_id << 32 | row << 16 | column
  uint32_t node;
} __attribute__((packed));

/// The memory build_records() works in, kept from draw to draw: a capture's
/// draws make millions of fragments each, and fresh pages' faults cost
/// more than the work done on them.
struct BuildScratch {
  /// The fragments' keys, and the radix sort's other half, which once the
  /// keys are sorted holds build_records()'s run of encoded records.
  LargeArray<OrderKey> order, sorted;
  LargeArray<uint64_t> coverage;  ///< each node's coverage (0: no fragment)
};

/// Where build_records() puts a draw's records: a run of `count` whole
/// records (`bytes` of them) at a time, in API order. Returns "" or an error.
using RecordSink = std::function<std::string(const uint8_t* records, size_t bytes, size_t count)>;

/// The fragments build_fragments() makes, encoded as the trace records of
/// `header` (its size and spp; DepthMode::kPerSample, ColorFormat::kRgbF32;
/// the draw table may be empty) by the same threads that order them, and
/// given to `sink` a run of records at a time (the runs' memory is
/// scratch.sorted's, reused), so that the trace's writer only frames and
/// compresses them (TraceWriter::write_records()) and a draw's records are
/// never all in memory at once. `scratch` keeps the arrays from call to
/// call. `out` gets the counts (its bytes are left empty). Returns "", why a
/// node is out of range or a fragment invalid, or the sink's error.
std::string build_records(const NodeView& nodes, uint32_t draw_id, const std::vector<DrawPart>& parts, bool clamp,
                          const TraceHeader& header, BuildScratch& scratch, const RecordSink& sink, EncodedDraw& out);
/// The same with scratch memory of its own, the records in `out.bytes`.
std::string build_records(const NodeView& nodes, uint32_t draw_id, const std::vector<DrawPart>& parts, bool clamp,
                          const TraceHeader& header, EncodedDraw& out);

/// A CapturedFragment (its depths at z) as the trace's Fragment (DepthMode::kPerSample).
Fragment to_trace_fragment(const CapturedFragment& f, const float* z);

}  // namespace ropsim::glcapture
