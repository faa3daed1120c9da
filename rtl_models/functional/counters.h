// The event counters of the functional ROP, each declared once with its name,
// unit and meaning (the reports and docs/reports.md are generated from this
// list). Each stage of the functional ROP owns the counters it increments;
// a run's counters are the sum over its stages.
#pragma once
#include <cstdint>
#include <vector>

namespace ropsim {

// X(name, unit, meaning, scope): scope says which methods' reports list the
// counter (CounterScope): every method, the methods with blend passes (and
// every method on a frame of draw states), or slab.
#define ROPSIM_COUNTERS(X)                                                                                          \
  X(fragments, "fragments", "fragments processed", kAll)                                                            \
  X(samples_tested, "samples", "covered samples of those fragments", kAll)                                          \
  X(samples_depth_passed, "samples",                                                                                \
    "samples that passed the depth test (a2c, hashed, hashed-a2c: among the samples the mask kept)", kAll)          \
  X(samples_opacity_passed, "samples",                                                                              \
    "samples that passed the opacity decision (lk: the opacity test; enderton: the R chosen, with original of the " \
    "covered samples, some of which may fail the depth test; a2c, hashed, hashed-a2c: the mask)",                   \
    kAll)                                                                                                           \
  X(samples_written, "samples", "samples whose depth and colour were written (slab: mask bits of inserted layers)", \
    kAll)                                                                                                           \
  X(surface_id_changes, "events", "lk: new surfaces started by a bitmask conflict", kAll)                           \
  X(sorts, "fragments", "lk: fragments with 2 or more surviving samples to sort", kAll)                             \
  X(depth_bytes_read, "bytes",                                                                                      \
    "4 per depth-tested sample (binary32 depth; a2c, hashed, hashed-a2c: the samples the mask kept, none for a "    \
    "discarded fragment; slab: none, its layers hold the depth)",                                                   \
    kAll)                                                                                                           \
  X(depth_bytes_written, "bytes", "4 per written sample", kAll)                                                     \
  X(color_bytes_written, "bytes", "6 per written sample (RGB binary16); 4 on an 8-bit target (RGBA8)", kAll)        \
  X(tracker_bytes_read, "bytes", "lk: ceil((spp + surface_id_bits) / 8) per fragment", kAll)                        \
  X(tracker_bytes_written, "bytes", "lk: the same, per fragment with a surviving sample", kAll)                     \
  X(tiles_touched, "tiles", "8 x 8-pixel tiles whose state was allocated", kAll)                                    \
  X(samples_blended, "samples",                                                                                     \
    "blend passes: samples blended into the render targets; a frame's additive and other blended draws: samples "   \
    "blended into the colour",                                                                                      \
    kBlend)                                                                                                         \
  X(target_bytes_read, "bytes",                                                                                     \
    "render-target bytes read by the blend (read-modify-write; blend: none for a draw replacing every channel); a " \
    "frame's blended draws: 6 per sample of the colour they blend into (4 on an 8-bit target)",                     \
    kBlend)                                                                                                         \
  X(target_bytes_written, "bytes", "blend passes: render-target bytes written by the blend", kBlend)                \
  X(layer_bytes_read, "bytes", "slab: the pixel's layers, k (4 + 6 + ceil(b / 8)) + 1 per fragment", kSlab)         \
  X(layer_bytes_written, "bytes", "slab: the same, per fragment inserted (the layers rewritten)", kSlab)

/// Which methods' reports list a counter.
enum class CounterScope { kAll, kBlend, kSlab };

/// Event counts of one run.
struct Counters {
#define ROPSIM_X(name, unit, meaning, scope) uint64_t name = 0;
  ROPSIM_COUNTERS(ROPSIM_X)
#undef ROPSIM_X

  Counters& operator+=(const Counters& o) {
#define ROPSIM_X(name, unit, meaning, scope) name += o.name;
    ROPSIM_COUNTERS(ROPSIM_X)
#undef ROPSIM_X
    return *this;
  }
  /// The difference of two snapshots of one run's counters (o no later than this).
  Counters& operator-=(const Counters& o) {
#define ROPSIM_X(name, unit, meaning, scope) name -= o.name;
    ROPSIM_COUNTERS(ROPSIM_X)
#undef ROPSIM_X
    return *this;
  }
  /// Per-pixel state bytes moved: depth, colour, tracker, render targets and
  /// slab's layers, read and written.
  uint64_t state_bytes_read() const {
    return depth_bytes_read + tracker_bytes_read + target_bytes_read + layer_bytes_read;
  }
  uint64_t state_bytes_written() const {
    return depth_bytes_written + color_bytes_written + tracker_bytes_written + target_bytes_written +
           layer_bytes_written;
  }
  /// Calls f(name, value) for every counter, in declaration order.
  template <class F>
  void for_each(F&& f) const {
#define ROPSIM_X(name, unit, meaning, scope) f(#name, name);
    ROPSIM_COUNTERS(ROPSIM_X)
#undef ROPSIM_X
  }
};

/// A statistic's description: its name, unit and one-line meaning.
struct StatDesc {
  const char* name;
  const char* unit;
  const char* meaning;
  CounterScope scope = CounterScope::kAll;  ///< counters: which methods' reports list it
};

/// The counters' descriptions, in declaration order.
inline const std::vector<StatDesc>& counter_descs() {
  static const std::vector<StatDesc> v = {
#define ROPSIM_X(name, unit, meaning, scope) {#name, unit, meaning, CounterScope::scope},
      ROPSIM_COUNTERS(ROPSIM_X)
#undef ROPSIM_X
  };
  return v;
}

}  // namespace ropsim
