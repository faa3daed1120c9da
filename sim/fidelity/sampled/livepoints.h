// Sampled cycle simulation from live-points (SMARTS: Wunderlich et al.,
// ISCA 2003), the building blocks: recording live-points in one functional
// pass, simulating one in detail, and the estimate with its confidence
// interval.
//
// ropsim's functional state does not depend on the hardware design (the
// image is bit-exact in every design), so one functional pass serves every
// design of a sweep. A *sampling unit* is a window of U consecutive fragments
// of the input; K units are placed systematically, the last ending with the
// input. Its *live-point* holds the W fragments before it (the warm-up) and
// its own, and the pre-state of only the pixels those fragments touch, as the
// golden model held them before the warm-up, with which lines of their 8 x 8
// tiles then held written values. A unit is simulated by
// the cycle model from its live-point: the warm-up fragments warm the ROP
// caches, the DRAM row buffers and the pipeline in detail, then the window
// is measured from the retirement of the W-th fragment to that of the
// (W + U)-th, with C more fragments behind it (the cool-down) so the window's
// last fragments pass a full pipeline. The run's figures are N times the mean per-fragment figure over
// the units, plus the last unit's tail (the pipeline's drain and the final
// cache flush after the input's last fragment), with a Student-t 95 %
// interval from the variance across units.
//
// What a live-point cannot know, being design-independent: which lines DRAM
// holds (fast clear consults it). A line of a tile the golden model had
// touched before the warm-up is taken to be in DRAM; one never touched, not.
// A line that a design still held dirty in a cache at that point is a cache
// hit either way once the warm-up has run, so the difference is confined to
// lines evicted before and never written back, which a warm-up longer than
// the caches' reach makes rare.
#pragma once
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "rtl_models/algo/buffers.h"
#include "rtl_models/algo/compression.h"
#include "rtl_models/config/hw_config.h"
#include "rtl_models/functional/frag_work.h"
#include "rtl_models/functional/fragment_source.h"
#include "rtl_models/functional/image.h"
#include "rtl_models/functional/method.h"
#include "rtl_models/functional/sample_store.h"
#include "rtl_models/memory/address_map.h"
#include "rtl_models/memory/compression_model.h"
#include "sim/fidelity/cycle/cycle_run.h"
#include "util/memory_budget.h"

namespace ropsim {

/// How the input is sampled.
struct SamplingParams {
  uint64_t unit_fragments = 2000;    ///< U: fragments per measured window
  uint64_t warmup_fragments = 4000;  ///< W: fragments simulated in detail before each window
  /// C: fragments simulated after each window but the last, so the window's
  /// last fragments pass a full pipeline, as in the full run (without them,
  /// the memory requests of the fragments in flight at the window's end
  /// would be missing from it).
  uint64_t cooldown_fragments = 2000;
  uint64_t units = 40;  ///< K: windows, placed every N / K fragments, the last ending the input
  /// T: fragments before each warm-up whose cache accesses warm the design's
  /// caches tag-only (no time, no DRAM traffic) before the detailed run.
  uint64_t warming_fragments = 50000;
  /// R: per design, the tag-only warming starts where the touches before the
  /// warm-up, walked backwards, have reached R times the design's cache
  /// capacity (all ROPs) in distinct lines -- at most T fragments back. A
  /// small cache is warmed by few fragments, a large one by many.
  double warming_reach = 4.0;
  /// An input whose units would simulate at least this share of it in detail
  /// is simulated whole, as one unit without warm-up (the full run, exactly).
  double max_detailed_share = 0.5;
};

/// What one fragment did to the per-pixel buffers, as the cache sees it
/// (design-independent): the samples whose depth it read, those it wrote.
struct Touch {
  uint64_t covered = 0;  ///< samples tested (their depth lines read)
  uint64_t written = 0;  ///< samples written (depth and colour lines; a routed draw's depth as depth_write says)
  uint16_t x = 0, y = 0;
  bool reached_write = false;  ///< not killed by the depth test: the writeback saw it (the tracker line)
  bool slab_kept = false;      ///< slab: its layers were rewritten
  /// A frame's opaque or blended draw (DrawRoute): no tracker line; its
  /// written samples' colour read first when reads_colour, their depth
  /// written only when depth_write.
  bool routed = false;
  bool reads_colour = false;
  bool depth_write = false;
};
/// The touch of fragment work w (after the functional stages ran on it).
Touch touch_of(const FragWork& w, bool slab);
/// Calls f(line, write, buffer) for every line a touch reads or writes, in
/// the order the pipeline does: the depth test's reads (depth, tracker, the
/// colour a blended draw reads), then the writeback's writes.
void for_each_touch_line(const Touch& x, const AddressMap& amap, bool tracker, bool slab,
                         const std::function<void(uint64_t, bool, Buffer)>& f);

/// A pixel of a live-point's tiles that held written values before its first
/// fragment: its lines are taken to be in DRAM (see above).
struct Resident {
  uint64_t written = 0;  ///< samples whose depth or colour differ from the clear values
  uint16_t x = 0, y = 0;
  bool tracker = false;  ///< lk: the tracker is not in its clear state
  bool layers = false;   ///< slab: the pixel holds layers
};

/// The state of the pixels a unit's fragments touch, as before the unit,
/// flat: pixel i is (x[i], y[i]), in (y, x) order; its samples are
/// depth[i spp ...], rgb[3 i spp ...] and planes[i spp ...].
struct PrePixels {
  bool tracker = false;  ///< lk: trackers held
  int slab_bits = 0;     ///< slab: layers held (0: none)
  std::vector<uint16_t> x, y;
  std::vector<float> depth;   ///< spp per pixel
  std::vector<uint16_t> rgb;  ///< 3 spp per pixel, binary16
  /// spp per pixel: each depth's plane key (compression.h, plane_key), what
  /// the rasterizer-plane depth encoder counts; kClearPlaneKey when cleared.
  std::vector<uint64_t> planes;
  std::vector<TrackerState> trackers;  ///< one per pixel when tracking
  std::vector<SlabPixel> slabs;        ///< one per pixel with SLAB layers
  size_t size() const { return x.size(); }
  /// Room for n pixels of spp samples (each then given by set).
  void resize(size_t n, int spp);
  /// Pixel i: (x, y) of st, clear's values if st never touched it. Distinct
  /// i may be set concurrently.
  void set(size_t i, const SampleStore& st, const PixelView& clear, uint32_t x, uint32_t y);
  /// Writes every pixel into st (a store of the same screen and buffers; the
  /// plane keys when st keeps them).
  void apply(SampleStore& st) const;
  size_t bytes() const;
};

/// The samples (depth, colour and plane key) of the pixels of a live-point's
/// tiles that hold written values but that none of its fragments touch, flat,
/// in (y, x) order. A design with compression or Hi-Z applies them with the
/// pre-state, so that the unit's store holds its 8 x 8 tiles whole, as the
/// compressor and Hi-Z see a memory tile: its class and farthest depth depend
/// on every pixel of it. Per-sample state a surface's encoding depends on
/// belongs here and in PrePixels, beside depth and colour.
struct TilePixels {
  std::vector<uint16_t> x, y;
  std::vector<float> depth;      ///< spp per pixel
  std::vector<uint16_t> rgb;     ///< 3 spp per pixel, binary16
  std::vector<uint64_t> planes;  ///< spp per pixel: plane keys, as PrePixels::planes
  size_t size() const { return x.size(); }
  /// Writes every pixel's depth, colour and (a store that keeps them) plane keys into st.
  void apply(SampleStore& st) const;
  size_t bytes() const;
};

struct LivePoint {
  uint64_t first = 0;               ///< the input's index of its first fragment (the warm-up's)
  uint64_t warmup = 0;              ///< fragments before the window (W, fewer at the input's start)
  uint64_t window = 0;              ///< U; then the cool-down, to the end of `fragments`
  std::vector<Fragment> fragments;  ///< the warm-up's, the window's, the cool-down's
  PrePixels pre;                    ///< the pixels they touch, as before `first`
  std::vector<Resident> resident;   ///< the pixels of those tiles holding written values before `first`
  TilePixels tiles;                 ///< the resident pixels' samples that `pre` does not hold
  std::vector<Touch> warming;       ///< the T fragments before `first` (fewer at the input's start)
};

/// What a library was recorded from: a trace file or a built-in scene.
struct InputIdentity {
  InputSpec spec;           ///< as given at recording (a trace's path, a scene's parameters)
  std::string description;  ///< InputSpec::describe() at recording
  bool from_trace = false;
  /// XXH3-64 of the trace file's bytes, or of the scene's header and
  /// fragment stream (livepoint_file.h, input_digest).
  uint64_t digest = 0;
};

struct LivePoints {
  InputIdentity input;
  /// The input was small (SamplingParams::max_detailed_share): one unit
  /// simulates it whole, and the estimates are the full run's, exactly.
  bool whole = false;
  TraceHeader header;
  MethodConfig method;
  SamplingParams params;
  uint64_t fragments = 0;  ///< N, the input's fragments
  std::vector<LivePoint> points;
  Counters counters;  ///< the functional pass's (exact)
  Image image;        ///< the golden image (exact)
  /// The points' fragments, touches and resident pixels in the run's memory
  /// budget (--memory-limit; the pre-states charge their own tiles).
  BudgetShare mem;
  /// Charges point's vectors to mem (once per point, when it is filled).
  void charge(const LivePoint& point);
  void charge() {
    for (const LivePoint& p : points) charge(p);
  }
};

/// Where a unit lies in the input: its first fragment (the warm-up's), its
/// window's first (start), and the end of its fragments (after the cool-down).
struct UnitSpan {
  uint64_t first = 0, start = 0, end = 0;
};
/// Unit k of K placed over n fragments by p as a library records it (U, K,
/// C and W final: W 0 for a whole input), the unit before it ending at
/// prev_end: window k starts at n - U - (K - 1 - k) (n / K), the last one
/// ending the input. Needs 1 <= K, U <= n / K, C <= n / K - U (or, whole, K
/// = 1 and U = n).
UnitSpan unit_span(uint64_t n, const SamplingParams& p, uint64_t k, uint64_t prev_end);

/// The sampling a library of an n-fragment input holds when p is asked for:
/// U at most n, K at most n / U, C within the period; an input whose units
/// would simulate at least p.max_detailed_share of it in detail is one whole
/// unit without warm-up (*whole set). The recording places its units by it,
/// and a library is checked against a run's sampling through it.
SamplingParams placed_sampling(const SamplingParams& p, uint64_t n, bool* whole = nullptr);

/// One functional pass over the input, recording K live-points, on `threads`
/// host threads (0: host_threads(), --threads; the library is the same for
/// every count). Throws UserError for a method with several passes or bad
/// parameters.
LivePoints record_livepoints(const InputSpec& in, const MethodConfig& method, const SamplingParams& p, int threads = 0);

/// One unit simulated in detail.
struct UnitRun {
  uint64_t window_cycles = 0;                                ///< from the W-th retirement to the (W + U)-th
  uint64_t window_bytes_read = 0, window_bytes_written = 0;  ///< DRAM, over the window
  /// Writes that made a clean line dirty, over the window: each is one line
  /// written to DRAM sooner or later, so this (not the window's write-backs,
  /// which lag) measures the window's share of the bytes written.
  uint64_t window_lines_dirtied = 0;
  uint64_t tail_lines_dirtied = 0;  ///< after the last retirement (the posted writes still pending)
  uint64_t tail_cycles = 0;         ///< after the window's last retirement: the cool-down, drain and cache flush
  uint64_t tail_bytes_read = 0, tail_bytes_written = 0;
  uint64_t total_cycles = 0;  ///< of the whole unit run
  uint64_t warming_used = 0;  ///< touches that warmed the caches tag-only (at most the live-point's)
  bool warming_short =
      false;  ///< the reach was not met within the live-point's touches, and the input had more before them
  uint64_t dram_max_channel_busy = 0;     ///< the busiest DRAM channel's busy cycles, whole unit run
  uint64_t dram_max_channel_service = 0;  ///< the busiest DRAM channel's service cycles (dram.h), whole unit run
  std::vector<UnitReport> units;          ///< every unit instance's activity over the whole unit run (no extras)
  /// Compression and Hi-Z (a design with them): the traffic over the window,
  /// after it, and over the whole unit run; the lines the window made dirty,
  /// per surface; the state the warming set before the run.
  bool compression = false;
  CompressionTraffic window_compression, tail_compression, run_compression;
  std::array<uint64_t, kBuffers> window_lines_dirtied_of{};
  CompressionModel::WarmState warmed;
  std::unique_ptr<SampleStore> state;  ///< the state after it (the pre-state's tiles, updated)
};
UnitRun simulate_livepoint(const LivePoints& lib, size_t unit, const HwConfig& hw);

/// An estimate and its 95 % confidence interval.
struct Estimate {
  double value = 0, low = 0, high = 0;
};

struct SampledRun {
  Estimate total_cycles, dram_bytes_read, dram_bytes_written;
  /// Every unit instance with its activities estimated for the whole run:
  /// each activity's share of the units' cycles (summed over the units' whole
  /// runs) times total_cycles.value. Fragments and samples: the units' sums.
  std::vector<UnitReport> units_estimated;
  /// total_cycles, units, dram utilisation and the bottleneck filled; the
  /// DRAM figures are the estimates' values (report printers take this).
  CycleStats stats;
  size_t units = 0;
  uint64_t fragments_detailed = 0;   ///< fragments the cycle model simulated (warm-ups and windows)
  uint64_t fragments_warmed = 0;     ///< touches that warmed the caches tag-only, summed over the units
  uint64_t units_warming_short = 0;  ///< units whose warming reach was cut short by the library's T
  double sim_seconds = 0;            ///< the units' host time (wall clock, workers included)
  double cpu_seconds = 0;            ///< the units' host time summed over the processes that ran them
  int jobs = 1;                      ///< worker processes
};
/// Where a sampled run's live-points came from.
struct LibrarySource {
  std::string path;    ///< the library file read, or "" (recorded by this run)
  double seconds = 0;  ///< host time to record or read it
};

/// Simulates every unit (in `jobs` worker processes when jobs > 1; the
/// figures are the same for every job count) and estimates the run's.
SampledRun run_sampled(const LivePoints& lib, const HwConfig& hw, int jobs = 1);

/// The 0.975 quantile of Student's t with dof degrees of freedom (>= 1).
double student_t975(uint64_t dof);

}  // namespace ropsim
