// The driver: feeds a fragment stream (a trace file or a built-in scene) to
// the functional models and collects counters, images and timing.
#pragma once
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "golden_model.h"
#include "scenes.h"
#include "trace.h"

namespace ropsim {

/// Where fragments come from: a trace file, or a scene rasterized on the fly.
struct InputSpec {
  std::string trace_path;  ///< non-empty: read this trace
  SceneParams scene;       ///< otherwise: build this scene
  uint32_t repeat = 1;     ///< draw the input this many times into one frame
  bool from_trace() const { return !trace_path.empty(); }
  std::string describe() const;
};

/// Opens the input, calls begin(header) once, then emit(fragment) for every
/// fragment in API order. Streams: a trace is never held in memory.
void stream_fragments(const InputSpec& in, const std::function<void(const TraceHeader&)>& begin,
                      const std::function<void(const Fragment&)>& emit);

/// Reads the whole input into memory (for benchmarks and tests).
struct FragmentList {
  TraceHeader header;
  std::vector<Fragment> fragments;
};
FragmentList load_fragments(const InputSpec& in);

struct FunctionalRun {
  TraceHeader header;
  Counters counters;
  Image image;
  size_t state_bytes = 0;
  double wall_seconds = 0;       ///< whole run: input, model and resolve
  std::optional<Image> reference;  ///< the reference method's image, when asked for
};

/// Runs the functional model of cfg.method over the input; with
/// with_reference also the A-buffer reference on the same stream.
FunctionalRun run_functional(const InputSpec& in, const GoldenConfig& cfg, bool with_reference = false);

/// Peak resident set size of this process in bytes (VmHWM), 0 if unknown.
size_t peak_rss_bytes();

}  // namespace ropsim
