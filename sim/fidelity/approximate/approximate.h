// The analytical timing model (--fidelity approximate).
//
// One functional pass over the input (the golden image, bit for bit, and each
// fragment's design-independent work: the samples it tested, passed, hashed,
// examined and wrote) drives a tag-only simulation of the design's ROP caches
// (the geometry, set index, LRU, write-allocate and fast-clear rules of
// rop_cache.h) and of the DRAM's row buffers (the channel, bank and row map of
// dram.h). No SystemC, no time-stepped simulation: from those counts the model
// computes, per epoch of the input, lower bounds on the cycles the design
// needs -- every unit's demand against its throughput, the depth test's
// memory latency against its requests in flight, the pixel scoreboard, the
// DRAM channels' service of their bursts -- and adds the epochs' largest
// bounds, the pipeline's fill and the final cache flush. With surface
// compression or Hi-Z on, the caches' DRAM traffic follows the cycle model's
// rules, tag-only (tag_compression.h), over the functional store's tiles. docs/architecture.md
// ("The analytical model") derives each term from the design's parameters;
// nothing is fitted to the cycle model's outputs.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "rtl_models/config/hw_config.h"
#include "rtl_models/functional/compressibility.h"
#include "rtl_models/functional/counters.h"
#include "rtl_models/functional/fragment_source.h"
#include "rtl_models/functional/image.h"
#include "rtl_models/functional/method.h"
#include "rtl_models/memory/compression_model.h"
#include "rtl_models/memory/dram.h"
#include "rtl_models/memory/rop_cache.h"
#include "sim/fidelity/common/bottleneck.h"
#include "sim/fidelity/common/run_outcome.h"

namespace ropsim {

/// The bounds the model computes, each a number of cycles: the sum over the
/// epochs of that bound alone (so the largest one, were it alone, would be
/// the time), and the bound that was the largest over the most cycles.
enum class ApproxBound : int {
  kSource,       ///< the trace source: fragments / source.fragments_per_clock
  kDistributor,  ///< the distributor: fragments / distributor.fragments_per_clock
  kUnit,         ///< the busiest unit of the busiest ROP: its initiation intervals summed
  kLatency,      ///< the depth test: each fragment's wait for its pixel's data / max_outstanding
  kScoreboard,   ///< pixel ordering: each fragment's time in flight / pixels_in_flight
  kDram,         ///< the busiest DRAM channel: its bursts served in order (bus, banks, row misses)
  kHazard,       ///< pixel ordering: chains of fragments of one pixel, each issued after the previous retired
};
constexpr int kApproxBounds = 7;
const char* to_string(ApproxBound b);

struct ApproxStats {
  HwConfig hw;
  uint64_t total_cycles = 0;     ///< the estimate: epochs + fill + final flush
  uint64_t pipeline_cycles = 0;  ///< the estimate without the final flush
  uint64_t fill_cycles = 0;      ///< the first fragment's trip through an empty pipeline (summed over passes)
  uint64_t flush_cycles = 0;     ///< the final cache flush's DRAM writes, served by the channels
  uint64_t epochs = 0;
  /// The busiest DRAM channel's service of all its bursts in arrival order,
  /// back to back (reads, write-backs and the final flush; summed over the
  /// passes): the DRAM's bound on the frame, as the cycle model's
  /// DramStats::max_channel_service.
  uint64_t dram_service_cycles = 0;
  /// The busiest DRAM channel's service cycles in the timed service (each
  /// burst at its request cycle), counted as the cycle model's
  /// DramStats::max_channel_service: per burst, from its request or the
  /// channel's previous burst's end, whichever is later, to the end of its
  /// transfer (summed over the passes).
  uint64_t dram_timed_service_cycles = 0;
  uint64_t epoch_fragments = 0;  ///< fragments per epoch (the buffering that lets the ROPs drift apart)
  /// Per bound: its sum over the epochs (cycles), and the cycles of the
  /// epochs in which it was the largest.
  std::array<double, kApproxBounds> bound_cycles{}, limiting_cycles{};
  /// The unit kind whose demand made kUnit (the busiest over the run).
  std::string busiest_unit;
  ApproxBound limiting = ApproxBound::kUnit;  ///< the bound largest over the most cycles
  /// What bounds the frame (bottleneck.h): the source, the distributor, each
  /// unit kind (the busiest ROP's initiation intervals) and the DRAM (the
  /// largest of dram_service_cycles, dram_timed_service_cycles and its bound
  /// over the epochs plus flush_cycles), against total_cycles.
  Bottleneck bottleneck;
  CacheStats cache;  ///< tag-only, summed over the ROPs
  DramStats dram;    ///< bytes, bursts and row hits of the tag-only DRAM
  /// Compression and Hi-Z (tag_compression.h), when the design has either.
  bool compression_on = false;
  CompressionTraffic compression;
  uint32_t listed = (1u << kBaseBuffers) - 1;  ///< as CycleStats::listed
  bool lists(int b) const { return (listed >> b) & 1u; }
};

struct ApproxRun : RunOutcome {
  ApproxStats stats;
};

/// Throws UserError for the reference method (no pipeline) and bad numerics;
/// TraceError for a bad trace.
ApproxRun run_approximate(const InputSpec& in, const GoldenConfig& method, const HwConfig& hw);

}  // namespace ropsim
