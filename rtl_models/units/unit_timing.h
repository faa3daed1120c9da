// The timing rules of the pipelined units, as plain functions of the
// hardware config (no SystemC): the SystemC units call them, and the RTL
// testbenches (tests/rtl, docs/rtl.md) check the SystemVerilog modules'
// measured latencies against the same functions.
#pragma once
#include <algorithm>
#include <cstdint>

#include "rtl_models/algo/bits.h"
#include "rtl_models/config/hw_config.h"

namespace ropsim {

struct UnitTiming {
  uint32_t interval;  ///< cycles before the next fragment may enter (>= 1)
  uint32_t latency;   ///< cycles from entry to the output (>= 1)
};

/// Alpha-reference generator: `hashes` hashes enter lanes per clock, over
/// ceil(hashes / lanes) clocks; the last leaves pipeline_depth cycles after
/// it entered.
inline UnitTiming alpha_ref_timing(const HwConfig::AlphaRef& cfg, uint32_t hashes) {
  const uint32_t interval = std::max<uint32_t>(1, ceil_div(hashes, cfg.lanes));
  return {interval, cfg.pipeline_depth + interval - 1};
}

/// Coverage tracker: one fragment per clock, latency_cycles each.
inline UnitTiming tracker_timing(const HwConfig::Tracker& cfg) { return {1, cfg.latency_cycles}; }

}  // namespace ropsim
