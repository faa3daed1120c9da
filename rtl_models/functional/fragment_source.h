// Where fragments come from, for every fidelity: a trace file read as it
// goes, or a built-in scene rasterized a triangle at a time. Both stream (an
// input is never held in memory whole) and repeat the input when asked, so
// the golden model and the cycle model see the same fragments in the same
// order through one protocol: header(), then next() until it returns false.
#pragma once
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "traces/format/trace.h"
#include "traces/scenes/scenes.h"

namespace ropsim {

/// Where fragments come from: a trace file, or a scene rasterized on the fly.
/// The most times an input is drawn into one frame (`--repeat`).
inline constexpr uint32_t kMaxRepeat = 1000;

struct InputSpec {
  std::string trace_path;  ///< non-empty: read this trace
  SceneParams scene;       ///< otherwise: build this scene
  uint32_t repeat = 1;     ///< draw the input this many times into one frame
  /// A trace's zstd payload decoded on a thread of its own (a core is spare
  /// for it; trace.h's TraceReader).
  bool decode_ahead = true;
  bool from_trace() const { return !trace_path.empty(); }
  std::string describe() const;
};

class FragmentSource {
 public:
  virtual ~FragmentSource() = default;
  const TraceHeader& header() const { return header_; }
  /// The next fragment in API order (the input drawn `repeat` times); false
  /// at the end. Throws TraceError for a bad trace record.
  virtual bool next(Fragment& f) = 0;
  /// Fragments delivered so far.
  uint64_t delivered() const { return delivered_; }
  /// A lower bound on the fragments the input holds (repeats included), known
  /// before reading it where its size tells (an uncompressed trace file: its
  /// bytes over the largest record's); 0 where nothing is known. For the
  /// up-front memory estimate (--memory-limit).
  virtual uint64_t fragments_at_least() const { return 0; }
  /// The exact number of fragments the input holds (repeats included), when
  /// known before reading it: a trace whose header records its count.
  virtual std::optional<uint64_t> fragments_known() const { return std::nullopt; }
  /// The share of the input consumed so far, in [0, 1], repeats included: a
  /// trace's file bytes read, a scene's triangles rasterized; for progress.
  virtual double consumed() const = 0;

 protected:
  TraceHeader header_;
  uint64_t delivered_ = 0;
};

/// Opens the input: reads the trace's header, or builds the scene. Throws
/// TraceError or SceneError for bad input.
std::unique_ptr<FragmentSource> open_fragments(const InputSpec& in);

/// Fragments held in memory (a live-point's, sampled simulation), in order.
std::unique_ptr<FragmentSource> fragments_from(const TraceHeader& h, const std::vector<Fragment>& fragments);

}  // namespace ropsim
