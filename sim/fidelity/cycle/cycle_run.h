// Runs the cycle-approximate SystemC pipeline over an input, in a fresh
// SystemC simulation context (so one process can run many), and gathers its
// statistics. Model code never prints: the report printers format CycleStats.
#pragma once
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "rtl_models/config/hw_config.h"
#include "rtl_models/core/timed_fifo.h"
#include "rtl_models/core/token.h"
#include "rtl_models/core/unit.h"
#include "rtl_models/functional/breakdown.h"
#include "rtl_models/functional/compressibility.h"
#include "rtl_models/functional/counters.h"
#include "rtl_models/functional/fragment_source.h"
#include "rtl_models/functional/image.h"
#include "rtl_models/functional/method.h"
#include "rtl_models/functional/sample_store.h"
#include "rtl_models/memory/compression_model.h"
#include "rtl_models/memory/dram.h"
#include "rtl_models/memory/rop_cache.h"
#include "rtl_models/observe/attribution.h"
#include "rtl_models/observe/interval_log.h"
#include "sim/fidelity/common/bottleneck.h"
#include "sim/fidelity/common/run_outcome.h"

namespace ropsim {

class FunctionalRop;

struct CycleOptions {
  std::string vcd_path;                             ///< non-empty: write a VCD waveform here (waveform.h)
  std::string gtkw_path;                            ///< with vcd_path, non-empty: its GTKWave save file here
  uint64_t vcd_first = 0, vcd_last = ~uint64_t{0};  ///< cycles [first, last] the waveform shows
  /// Every 65536 fragments: the fragments so far (every pass) and the share
  /// of the run's input consumed (passes included), in [0, 1].
  std::function<void(uint64_t fragments, double consumed)> progress;
  std::function<void(const FragToken&, uint64_t cycle)> retire_hook;  ///< every retired fragment
  /// Runs every unit in lockstep with SystemC time, none decoupled (unit.h).
  /// The results are identical, the waveform too; it is slower.
  bool lockstep = false;
  /// > 0: also record the run's statistics per interval of this many cycles
  /// (CycleRun::intervals, --stats-interval).
  uint64_t stats_interval = 0;
  /// Split the counters by draw and sum them per pixel (CycleRun::breakdown,
  /// --per-draw, --maps); per draw also the cycles attributed to it.
  BreakdownRequest breakdown;
};

struct UnitReport {
  std::string name;  ///< SystemC instance name
  std::string kind;  ///< trace_source, distributor, pixel_ordering, depth_test, ...
  int rop = -1;      ///< ROP index, -1 for shared units
  UnitStats stats;
  std::vector<Unit::Extra> extras;
};

/// One pass of a multi-pass method: its cycles and its memory traffic. Each
/// pass ends with the caches flushed (the render targets are complete before
/// the next pass reads them); the next pass starts at the cycle after.
struct PassStats {
  std::string name;              ///< total_alpha, stochastic, accumulate (method.h PassKind)
  uint64_t total_cycles = 0;     ///< to the end of the pass's cache flush
  uint64_t pipeline_cycles = 0;  ///< to the pass's last retirement
  CacheStats cache;              ///< summed over the ROP caches
  DramStats dram;
};

struct CycleStats {
  HwConfig hw;
  uint64_t period_ps = 0;                                 ///< simulated clock period
  uint64_t total_cycles = 0;                              ///< to the end of the final cache flush
  uint64_t pipeline_cycles = 0;                           ///< to the retirement of the last fragment
  double frame_time_us = 0;                               ///< total_cycles at the configured clock
  double fragments_per_clock = 0, samples_per_clock = 0;  ///< over total_cycles
  std::vector<UnitReport> units;
  std::vector<FifoStats> fifos;
  std::vector<CacheStats> caches;  ///< per ROP
  DramStats dram;
  /// Surface compression and Hi-Z (compression_model.h), when the design has them.
  bool compression_on = false;
  CompressionTraffic compression;
  double dram_peak_gbps = 0;      ///< channels x bytes/clock x GHz (GB/s = 1e9 B/s)
  double dram_achieved_gbps = 0;  ///< bytes moved / frame time
  double dram_utilization = 0;    ///< busiest channel's busy cycles / total cycles
  bool memory_bound = false;      ///< the bottleneck is the DRAM's bandwidth (bottleneck.kind)
  Bottleneck bottleneck;          ///< what bounds the frame (bottleneck.h; the report formats it)
  uint64_t activations = 0;       ///< SystemC process activations: cycles in which some unit ran (host cost)
  uint64_t unit_runs = 0;         ///< unit activations summed over the units (decoupled units run inside others')
  bool decoupled = false;         ///< units without timed shared state ran ahead of SystemC time
  size_t tokens_allocated = 0;    ///< fragment tokens ever in flight at once (upper bound)
  /// Multi-pass methods: each pass (the figures above are their sums); empty
  /// for a single pass.
  std::vector<PassStats> passes;
  /// Bit b: the report lists Buffer(b) -- depth, colour and tracker always;
  /// the render targets and slab's layers when the method has them.
  uint32_t listed = (1u << kBaseBuffers) - 1;
  bool lists(int b) const { return (listed >> b) & 1u; }
};

/// The cycle model's bounds (s.units, s.dram and s.total_cycles set): per
/// unit kind the largest busy cycles of one instance (a ROP's, summed over
/// the passes), and the DRAM's busiest channel's service cycles
/// (DramStats::max_channel_service).
std::vector<ResourceBound> cycle_bounds(const CycleStats& s);
/// classify_bottleneck(cycle_bounds(s), s.total_cycles).
Bottleneck classify_bottleneck(const CycleStats& s);

struct CycleRun : RunOutcome {
  std::unique_ptr<SampleStore> state;  ///< the final per-sample state
  CycleStats stats;
  double sim_seconds = 0;  ///< sc_start alone (wall_seconds: elaboration and resolve too)
  /// With CycleOptions::stats_interval: the statistics per interval; each
  /// column adds up to the run's total.
  std::unique_ptr<IntervalLog> intervals;
  /// With CycleOptions::breakdown: per draw (counters, cycles, DRAM bytes) and per pixel.
  std::unique_ptr<RunBreakdown> breakdown;
  /// With CycleOptions::breakdown.per_pixel: the per-tile figures
  /// (attribution.h) over the distributor's tiles_x x tiles_y screen tiles.
  std::unique_ptr<Attribution> tiles;
  uint32_t tiles_x = 0, tiles_y = 0;
};

/// The cycle model's per-tile maps (--maps; attribution.h), declared once:
/// the map's (file) name, unit and meaning. Each sums over the tiles to a
/// report figure (the meaning names it).
const std::vector<StatDesc>& tile_map_descs();
/// Map i of tile_map_descs(): its value per distributor tile, row by row
/// (CycleRun::tiles_x per row).
const std::vector<uint64_t>& tile_map(const Attribution& a, size_t i);

/// Throws UserError for the reference method (it has no pipeline)
/// and TraceError for a bad trace.
CycleRun run_cycle(const InputSpec& in, const GoldenConfig& method, const HwConfig& hw, const CycleOptions& opt = {});
/// The same over the input open_input returns (called once per pass, each
/// call a fresh read of the same fragments: fragments_from() for a frame held
/// in memory).
CycleRun run_cycle(const std::function<std::unique_ptr<FragmentSource>()>& open_input, const GoldenConfig& method,
                   const HwConfig& hw, const CycleOptions& opt = {});

}  // namespace ropsim
