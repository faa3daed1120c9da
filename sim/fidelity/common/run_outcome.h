// What every fidelity's run gives, declared once: the functional, cycle and
// approximate results extend it with their own figures (a sampled run's come
// from its live-point library: sim/fidelity/run.h).
#pragma once
#include <cstddef>

#include "rtl_models/functional/counters.h"
#include "rtl_models/functional/image.h"
#include "traces/format/draw_state.h"
#include "traces/format/trace.h"

namespace ropsim {

struct RunOutcome {
  TraceHeader header;               ///< the input's
  Counters counters;                ///< the functional ROP's counters of the whole run
  DrawKindCounts kind_fragments{};  ///< fragments by their draw's kind (a frame of draw states)
  Image image;                      ///< the resolved image
  size_t state_bytes = 0;           ///< bytes of the final per-sample state the run kept
  double wall_seconds = 0;          ///< host time of the whole run: input, model and resolve
};

}  // namespace ropsim
