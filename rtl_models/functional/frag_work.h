// The per-fragment work record of the functional ROP: the fragment, its
// pixel's state, and what each stage has decided for it so far. The golden
// model keeps one and runs every stage on it; the cycle model's token carries
// one through the units, each unit running one stage on it.
#pragma once
#include <cstdint>

#include "rtl_models/algo/tracker.h"
#include "rtl_models/functional/sample_store.h"
#include "traces/format/draw_state.h"
#include "traces/format/trace.h"

namespace ropsim {

struct FragWork {
  const Fragment* f = nullptr;  ///< the fragment (not copied: the golden model's input, the token's own)
  PixelRef px{};                ///< the pixel's state (FunctionalRop::fetch)

  // Depth test.
  uint64_t covered = 0;    ///< samples tested: the coverage (a2c: AND its sample mask)
  uint64_t survivors = 0;  ///< samples that passed the depth test (S)
  uint32_t m = 0;          ///< popcount(survivors)
  float z[64];             ///< the fragment's depth at each tested sample

  // Per-method payloads, each filled by the stages its method uses. A run has
  // one method, so they share storage; each is only ever read as itself.
  struct Lk {
    TrackResult track;  ///< the tracker's decision (n, surface id)
    uint8_t order[64];  ///< survivors sorted by stored depth (order[0..m))
    uint32_t ref[64];   ///< alpha reference of the j-th sorted survivor order[j]
  };
  struct Enderton {
    uint32_t chosen;  ///< R = floor(alpha n + xi): the samples chosen (n: m, or the covered with `original`)
    uint32_t count;   ///< samples to write: R (original: the chosen that passed the depth test)
    int list[64];     ///< list[0..count): the samples to write, in choice order
  };
  struct Naive {
    uint32_t ref[64];  ///< random reference of survivor sample i, at index i
  };
  struct Slab {
    float z;        ///< the fragment's depth: the nearest of its covered samples'
    uint64_t mask;  ///< its stratified b-bit coverage mask (not occluded when it reaches the write)
    bool kept;      ///< the write inserted it (false: it was the furthest beyond k, dropped)
  };
  union {
    Lk lk;              ///< lk
    Enderton enderton;  ///< enderton
    Naive naive;        ///< naive
    Slab slab;          ///< slab
  };
  FragWork() : lk() {}

  // Opacity test and write.
  uint64_t written = 0;  ///< samples whose depth and colour were written

  // The fragment's draw (a trace of draw states; blend: always).
  const DrawState* draw = nullptr;       ///< the fragment's draw state (the depth test looks it up)
  DrawRoute route = DrawRoute::kMethod;  ///< its path: the method's, opaque or blended (the depth test sets it)
  uint64_t depth_written = 0;  ///< samples whose depth was written (the method's writes, or the draw's depth mask)

  /// No sample survived the depth test: the fragment leaves the ROP there.
  bool killed() const { return m == 0; }
};

}  // namespace ropsim
