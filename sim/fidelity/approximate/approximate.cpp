// The analytical timing model (docs/architecture.md "The analytical
// model"): the functional pass records each fragment's work, then a
// tag-only model of the caches, the compression metadata and DRAM replays it
// epoch by epoch and bounds the cycles. One concern in one file: Model holds
// the epoch state that run_approximate feeds, and the bounds read both.
#include "sim/fidelity/approximate/approximate.h"

#include <algorithm>
#include <chrono>
#include <functional>
#include <future>
#include <memory>

#include "rtl_models/algo/bits.h"
#include "rtl_models/algo/depth.h"
#include "rtl_models/functional/functional_rop.h"
#include "rtl_models/functional/pass_loop.h"
#include "rtl_models/memory/address_map.h"
#include "rtl_models/memory/cache_tags.h"
#include "rtl_models/memory/line_set.h"
#include "rtl_models/memory/tag_cache.h"
#include "rtl_models/memory/tag_compression.h"
#include "rtl_models/memory/tag_dram.h"
#include "rtl_models/sorter/sort_algorithm.h"
#include "rtl_models/top/memory_estimate.h"
#include "rtl_models/top/store_tile_source.h"
#include "rtl_models/top/surface_compression.h"
#include "rtl_models/units/rop_ownership.h"
#include "sim/fidelity/cycle/cycle_run.h"
#include "util/errors.h"
#include "util/memory_budget.h"
#include "util/progress.h"

namespace ropsim {

const char* to_string(ApproxBound b) {
  switch (b) {
    case ApproxBound::kSource:
      return "source";
    case ApproxBound::kDistributor:
      return "distributor";
    case ApproxBound::kUnit:
      return "unit";
    case ApproxBound::kLatency:
      return "latency";
    case ApproxBound::kScoreboard:
      return "scoreboard";
    case ApproxBound::kDram:
      return "dram";
    case ApproxBound::kHazard:
      return "hazard";
  }
  return "?";
}

namespace {

// ------------------------------------------------------------ the model

enum UnitKind : int { kOrdering, kDepthTest, kTracker, kSorter, kAlphaRef, kWriteback, kBlend, kUnitKinds };
const char* kUnitNames[kUnitKinds] = {
    "pixel_ordering", "depth_test", "coverage_tracker", "sample_sorter", "alpha_ref_gen", "writeback", "blend"};

/// What one ROP did in the current epoch.
struct RopEpoch {
  std::array<uint64_t, kUnitKinds> demand{};  ///< initiation intervals summed, per unit kind
  uint64_t hold = 0;                          ///< depth test: cycles each fragment waited for its data, summed
  uint64_t residence = 0;                     ///< cycles each fragment was in flight (issue to retire), summed
  double issued_by = 0;                       ///< pixel ordering: the cycle after its last issue (hazard chain)
  double accepted_by = 0;                     ///< depth test: the cycle it could accept its next fragment
};

/// One ROP's depth test in time, as DepthTest serves fragments: it accepts a
/// fragment once the one before it has taken its initiation interval and
/// one of its max_outstanding slots is free; a fragment holds its slot until
/// its data is there (the first whose data arrives leaves first).
struct DepthSlots {
  std::vector<double> ready;  ///< min-heap: the cycles the occupied slots' data arrives
  double next = 0;            ///< the cycle the unit can accept again (the initiation interval)
  /// The acceptance cycles of the ROP's last `queued` fragments (a ring): a
  /// fragment enters the ROP's queue ahead of the depth test once the one
  /// `queued` before it has left it.
  std::vector<double> accepted;
  size_t at = 0;
};

struct PassResult {
  uint64_t cycles = 0, fill = 0, flush = 0, epochs = 0;
  uint64_t dram_service = 0;        ///< the busiest channel's service of all its bursts, the final flush's too
  uint64_t dram_timed_service = 0;  ///< the same, of the timed service (as the cycle model counts it)
};

/// What the model needs of one fragment, from the functional pass: its
/// pixel and the work each stage did (design-independent).
struct FragRec {
  uint64_t covered = 0, survivors = 0, written = 0;  ///< sample masks: tested, passed the depth test, written
  uint16_t x = 0, y = 0;
  uint16_t m = 0;                                  ///< popcount(survivors); 0: killed by the depth test
  uint16_t hashes = 0, examined = 0, blended = 0;  ///< the reference, writeback and blend stages' counts
  /// A frame's opaque or blended draw (DrawRoute): its colour is written, and
  /// read when reads_colour; its depth only when depth_write.
  DrawRoute route = DrawRoute::kMethod;
  bool slab_kept : 1;     ///< slab: its layers were rewritten
  bool reads_colour : 1;  ///< a blend pass (blend) or a routed draw reads the colour it writes
  bool depth_write : 1;   ///< a routed draw: it writes depth
  bool depth_test : 1;    ///< its draw tests depth (slab over a pre-pass: it reads the covered samples' depth)
  bool hiz_test : 1;      ///< Hi-Z may reject it (its test is the methods' own, or LESS / LEQUAL)
  float zmin = 1.0f;      ///< the nearest depth of its tested samples (Hi-Z)
  FragRec() : slab_kept(false), reads_colour(false), depth_write(false), depth_test(true), hiz_test(false) {}
  bool killed() const { return m == 0; }
};
static_assert(sizeof(FragRec) == kApproxRecordBytes, "memory_estimate.h's kApproxRecordBytes is a FragRec's size");

class Model {
 public:
  /// comp: compression and Hi-Z (null: neither), its DRAM this pass's.
  Model(const HwConfig& hw, FunctionalRop& rop, LineSet& in_dram, ApproxStats& out, TagOnlyCompression* comp)
      : rop_demand(hw.distributor.rop_units),
        hw_(hw),
        out_(out),
        owner_(hw.distributor, rop.header().width),
        amap_(rop.header().width, rop.header().spp, rop.setup().tracker_bytes, hw.cache.line_bytes,
              rop.setup().bytes.stored, rop.setup().slab_bytes),
        dram_(hw.dram),
        sorter_(make_sorter(hw.sorter.kind, rop.header().spp)),
        rops_(hw.distributor.rop_units),
        width_(rop.header().width),
        retire_(size_t(ceil_div(rop.header().width, 8u)) * ceil_div(rop.header().height, 8u) * 64, -1e300),
        window_issue_(hw.distributor.rop_units, std::vector<double>(hw.ordering.window, -1e300)),
        window_at_(hw.distributor.rop_units, 0),
        slots_(hw.distributor.rop_units),
        delivery_rate_(std::min(double(hw.source.fragments_per_clock), double(hw.distributor.fragments_per_clock))),
        comp_(comp) {
    if (comp_) comp_->set_dram(&dram_);
    for (uint32_t r = 0; r < hw.distributor.rop_units; ++r)
      caches_.push_back(
          std::make_unique<TagOnlyCache>(hw.cache, hw.depth_test.max_outstanding, dram_, in_dram, comp_, r));
    const MethodTraits& mt = rop.traits();
    blend_pass_ = is_blend_pass(rop.pass());
    tracker_ = rop.pass_uses_tracker();
    sorter_on_ = mt.sorter && !blend_pass_;
    reference_on_ = mt.reference && !blend_pass_;
    tracker_unit_ = mt.tracker && !blend_pass_;
    slab_ = rop.setup().cfg.method == Method::kSlab;
    prepass_ = rop.setup().prepass;
    color_ = stochastic_writes_colour_buffer(rop.setup().cfg.method, prepass_);
    // Over a pre-pass, +ac's stochastic colour goes to the accumulation
    // target and +depth marks the transmittance target (method.h).
    if (stochastic_colour_in_accum(rop.setup().cfg.method, prepass_)) marks_ = Buffer::kAccum;
    if (stochastic_marks_transmittance(rop.setup().cfg.method, prepass_)) marks_ = Buffer::kTransmittance;
    const PassKind p = rop.pass();
    trans_ = p == PassKind::kTotalAlpha || p == PassKind::kWboit;
    accum_ = p == PassKind::kAccumulate || p == PassKind::kWboit || p == PassKind::kFramebuffer;
    framebuffer_ = p == PassKind::kFramebuffer;
    const auto& d = hw.distributor;
    const auto& o = hw.ordering;
    epoch_ = uint64_t(d.rop_units) * (d.fifo_depth + d.latency_cycles + o.window + o.fifo_depth + o.latency_cycles +
                                      hw.depth_test.max_outstanding);
    out_.epoch_fragments = epoch_;
    // A ROP's queue ahead of its depth test: its input FIFO, the ordering
    // unit's window and FIFO and their pipeline registers (the epoch's terms).
    const size_t queued = size_t(d.fifo_depth) + d.latency_cycles + o.window + o.fifo_depth + o.latency_cycles;
    for (auto& ds : slots_) ds.accepted.assign(queued, -1e300);
  }

  /// One fragment, after the functional stages ran on w: its costs.
  void fragment(const FragRec& w) {
    const FragRec& f = w;
    const uint32_t hashes = w.hashes, examined = w.examined, blended = w.blended;
    const uint32_t r = owner_.rop_of(f.x, f.y);
    TagOnlyCache& c = *caches_[r];
    c.next_fragment(uint32_t(f.y) * uint32_t(width_) + f.x);
    RopEpoch& e = rops_[r];
    const HwConfig& hw = hw_;
    // Depth test: the pixel's state, read through the cache; the fragment
    // waits for the slowest of its lines (unloaded: the queueing is the DRAM
    // bound's).
    uint64_t wait = 0;
    auto rd = [&](uint64_t line, Buffer b) {
      uint64_t lat = 0;
      c.read(line, b, lat);
      wait = std::max(wait, lat);
    };
    const uint32_t covered = uint32_t(__builtin_popcountll(w.covered));
    // The cycle the depth test accepts it: not before the distributor
    // delivered it -- in input order, at the source's and its own rate, not
    // before the epoch's start, and only into room in its ROP's queue ahead
    // of the depth test (a full queue blocks every ROP) -- and once the
    // unit's previous fragment took its interval and a slot is free. Its
    // reads are requested then, and queue in DRAM behind every burst
    // requested before them (DramTags' timed service).
    DepthSlots& ds = slots_[r];
    delivered_ = std::max({delivered_ + 1 / delivery_rate_, t_, ds.accepted[ds.at]});
    double enter = std::max(delivered_, ds.next);
    if (ds.ready.size() == hw.depth_test.max_outstanding) {
      std::pop_heap(ds.ready.begin(), ds.ready.end(), std::greater<double>());
      enter = std::max(enter, ds.ready.back());
      ds.ready.pop_back();
    }
    dram_.set_now(uint64_t(enter + 0.5));
    if (slab_ && w.route == DrawRoute::kMethod) {
      amap_.for_each_layer_line(f.x, f.y, [&](uint64_t l) { rd(l, Buffer::kLayers); });
      if (prepass_ && w.depth_test)  // over a pre-pass's background: the covered samples' depth too
        amap_.for_each_sample_line(Buffer::kDepth, f.x, f.y, w.covered, [&](uint64_t l) { rd(l, Buffer::kDepth); });
    } else if (hiz_rejects(w)) {
      // Hierarchical Z: every tested sample lies beyond its tile's farthest
      // stored depth; the fragment reads nothing and retires at the depth test.
    } else {
      amap_.for_each_sample_line(Buffer::kDepth, f.x, f.y, w.covered, [&](uint64_t l) { rd(l, Buffer::kDepth); });
      if (tracker_) amap_.for_each_tracker_line(f.x, f.y, [&](uint64_t l) { rd(l, Buffer::kTracker); });
      if (trans_)
        amap_.for_each_sample_line(Buffer::kTransmittance, f.x, f.y, w.survivors,
                                   [&](uint64_t l) { rd(l, Buffer::kTransmittance); });
      if (accum_ && (!framebuffer_ || w.reads_colour))
        amap_.for_each_sample_line(Buffer::kAccum, f.x, f.y, w.survivors, [&](uint64_t l) { rd(l, Buffer::kAccum); });
      if (w.route != DrawRoute::kMethod && w.reads_colour)
        amap_.for_each_sample_line(Buffer::kColor, f.x, f.y, w.survivors, [&](uint64_t l) { rd(l, Buffer::kColor); });
    }
    e.demand[kOrdering] += 1;
    const uint32_t test_ii = std::max<uint32_t>(1, ceil_div(covered, hw.depth_test.samples_per_clock));
    e.demand[kDepthTest] += test_ii;
    e.hold += wait;
    ds.next = enter + test_ii;
    ds.accepted[ds.at] = enter;
    ds.at = ds.at + 1 == ds.accepted.size() ? 0 : ds.at + 1;
    e.accepted_by = std::max(e.accepted_by, ds.next);
    ds.ready.push_back(enter + double(wait));
    std::push_heap(ds.ready.begin(), ds.ready.end(), std::greater<double>());
    uint64_t res = hw.ordering.latency_cycles + wait;
    if (!w.killed()) {
      res += hw.depth_test.latency_cycles;
      if (blend_pass_) {
        e.demand[kBlend] += std::max<uint32_t>(1, ceil_div(blended, hw.blend.samples_per_clock));
        res += hw.blend.latency_cycles;
        if (trans_)
          amap_.for_each_sample_line(Buffer::kTransmittance, f.x, f.y, w.survivors,
                                     [&](uint64_t l) { c.write(l, Buffer::kTransmittance); });
        if (accum_)
          amap_.for_each_sample_line(Buffer::kAccum, f.x, f.y, w.survivors,
                                     [&](uint64_t l) { c.write(l, Buffer::kAccum); });
        if (framebuffer_)  // blend: `written` holds the samples whose depth its draw wrote
          amap_.for_each_sample_line(Buffer::kDepth, f.x, f.y, w.written,
                                     [&](uint64_t l) { c.write(l, Buffer::kDepth); });
      } else if (w.route != DrawRoute::kMethod) {
        // An opaque or blended draw: through the bypassed units, one clock
        // each, to the writeback (the cycle model's pass-through).
        const uint32_t bypassed = uint32_t(tracker_unit_) + uint32_t(sorter_on_) + uint32_t(reference_on_);
        if (tracker_unit_) e.demand[kTracker] += 1;
        if (sorter_on_) e.demand[kSorter] += 1;
        if (reference_on_) e.demand[kAlphaRef] += 1;
        res += bypassed;
        e.demand[kWriteback] += std::max<uint32_t>(1, ceil_div(examined, hw.writeback.samples_per_clock));
        res += hw.writeback.latency_cycles;
        if (w.depth_write)
          amap_.for_each_sample_line(Buffer::kDepth, f.x, f.y, w.written,
                                     [&](uint64_t l) { c.write(l, Buffer::kDepth); });
        amap_.for_each_sample_line(Buffer::kColor, f.x, f.y, w.written,
                                   [&](uint64_t l) { c.write(l, Buffer::kColor); });
      } else {
        if (tracker_unit_) {
          e.demand[kTracker] += 1;
          res += hw.tracker.latency_cycles;
        }
        if (sorter_on_) {
          e.demand[kSorter] += sorter_->interval_cycles(int(w.m));
          res += sorter_->latency_cycles(int(w.m));
        }
        if (reference_on_) {
          const uint32_t ii = std::max<uint32_t>(1, ceil_div(hashes, hw.alpha_ref.lanes));
          e.demand[kAlphaRef] += ii;
          res += hw.alpha_ref.pipeline_depth + ii - 1;
        }
        e.demand[kWriteback] += std::max<uint32_t>(1, ceil_div(examined, hw.writeback.samples_per_clock));
        res += hw.writeback.latency_cycles;
        amap_.for_each_sample_line(Buffer::kDepth, f.x, f.y, w.written,
                                   [&](uint64_t l) { c.write(l, Buffer::kDepth); });
        if (color_)
          amap_.for_each_sample_line(Buffer::kColor, f.x, f.y, w.written,
                                     [&](uint64_t l) { c.write(l, Buffer::kColor); });
        if (marks_ != Buffer::kDepth)
          amap_.for_each_sample_line(marks_, f.x, f.y, w.written, [&](uint64_t l) { c.write(l, marks_); });
        if (tracker_) amap_.for_each_tracker_line(f.x, f.y, [&](uint64_t l) { c.write(l, Buffer::kTracker); });
        if (slab_ && w.slab_kept) amap_.for_each_layer_line(f.x, f.y, [&](uint64_t l) { c.write(l, Buffer::kLayers); });
      }
    }
    e.residence += res;
    // Pixel ordering's chain: the fragment issues once its pixel's previous
    // fragment has retired and once the fragment `window` before it in this
    // ROP has left the window, and not before the epoch starts.
    {
      std::vector<double>& ring = window_issue_[r];
      size_t& at = window_at_[r];
      double& ret = retire_[amap_.pixel_index(f.x, f.y)];  // tile-major: neighbours share host lines
      const double issue = std::max({t_, ring[at] + 1, ret + 1});
      ring[at] = issue;
      at = at + 1 == ring.size() ? 0 : at + 1;
      ret = issue + double(res);
      e.issued_by = std::max(e.issued_by, issue + 1);
    }
    if (first_) {
      first_ = false;
      // Source (visible the clock after), distributor, then the fragment's own trip.
      fill_ = 1 + hw.distributor.latency_cycles + res;
    }
    if (++in_epoch_ == epoch_) close_epoch();
  }

  PassResult finish() {
    if (in_epoch_) close_epoch();
    PassResult p;
    p.fill = fill_;
    p.cycles = uint64_t(t_ + 0.5);
    // The final flush starts when the last fragment retires; its writes
    // queue behind the channels' backlog.
    // With compression, the state bits follow the data, and a compressed
    // line's write leaves compress_latency_cycles after the flush starts.
    std::vector<uint64_t> before, after;
    dram_.clocks(before);
    const uint64_t compressed_before = comp_ ? compressed_writes(comp_->stats()) : 0;
    for (auto& c : caches_) c->flush();
    if (comp_) comp_->flush();
    dram_.clocks(after);
    double tail = 0;
    for (size_t i = 0; i < after.size(); ++i) tail = std::max(tail, backlog_[i] + double(after[i] - before[i]));
    if (comp_ && compressed_writes(comp_->stats()) != compressed_before)
      tail += double(hw_.compression.compress_latency_cycles);
    p.flush = uint64_t(std::max(0.0, tail - double(fill_)) + 0.5);
    p.dram_service = dram_.max_clock();
    p.dram_timed_service = dram_.max_timed_service();
    p.epochs = epochs_;
    for (auto& c : caches_) out_.cache += c->stats();
    const DramStats& d = dram_.stats();
    for (size_t b = 0; b < size_t(kBuffers); ++b) {
      out_.dram.bytes_read[b] += d.bytes_read[b];
      out_.dram.bytes_written[b] += d.bytes_written[b];
    }
    out_.dram.reads += d.reads;
    out_.dram.writes += d.writes;
    out_.dram.row_hits += d.row_hits;
    out_.dram.row_misses += d.row_misses;
    out_.dram.max_channel_busy += dram_.max_busy();
    return p;
  }

  std::array<double, kUnitKinds> unit_cycles{};
  /// Per ROP and unit kind: its initiation intervals summed over the pass.
  std::vector<std::array<double, kUnitKinds>> rop_demand;

 private:
  /// Line writebacks of compressed tiles (a class above 0), every surface.
  static uint64_t compressed_writes(const CompressionTraffic& t) {
    uint64_t n = 0;
    for (const auto& per : t.writes_per_class)
      for (size_t j = 1; j < per.size(); ++j) n += per[j];
    return n;
  }
  /// Hi-Z, as the cycle model's depth test applies it: a fragment with
  /// tested samples whose draw Hi-Z may reject, tested against its tile's
  /// bound; a rejected fragment never had a surviving sample (the bound is
  /// conservative), else the model is broken.
  bool hiz_rejects(const FragRec& w) {
    if (!comp_ || !comp_->hiz() || !w.covered || !w.hiz_test) return false;
    if (!comp_->hiz_rejects(w.x, w.y, w.zmin)) return false;
    if (w.survivors)
      throw InternalError("Hi-Z never rejects a fragment that passes: pixel (" + std::to_string(w.x) + ", " +
                          std::to_string(w.y) + ") had surviving samples");
    uint64_t lines = 0;
    amap_.for_each_sample_line(Buffer::kDepth, w.x, w.y, w.covered, [&](uint64_t) { ++lines; });
    comp_->count_skipped(lines);
    return true;
  }
  void close_epoch() {
    std::array<double, kApproxBounds> b{};
    const double n = double(in_epoch_);
    b[int(ApproxBound::kSource)] = n / hw_.source.fragments_per_clock;
    b[int(ApproxBound::kDistributor)] = n / hw_.distributor.fragments_per_clock;
    int unit_kind = kOrdering;
    for (size_t r = 0; r < rops_.size(); ++r) {
      const RopEpoch& e = rops_[r];
      for (int k = 0; k < kUnitKinds; ++k) rop_demand[r][size_t(k)] += double(e.demand[size_t(k)]);
      for (int k = 0; k < kUnitKinds; ++k)
        if (double(e.demand[size_t(k)]) > b[int(ApproxBound::kUnit)]) {
          b[int(ApproxBound::kUnit)] = double(e.demand[size_t(k)]);
          unit_kind = k;
        }
      // The depth test's slots: Little's law on the fragments' waits for
      // their data (queueing in DRAM included), and the unit's own timeline
      // from the epoch's start to when it could accept the next fragment.
      b[int(ApproxBound::kLatency)] = std::max(
          {b[int(ApproxBound::kLatency)], double(e.hold) / hw_.depth_test.max_outstanding, e.accepted_by - t_});
      b[int(ApproxBound::kScoreboard)] =
          std::max(b[int(ApproxBound::kScoreboard)], double(e.residence) / hw_.ordering.pixels_in_flight);
      b[int(ApproxBound::kHazard)] = std::max(b[int(ApproxBound::kHazard)], e.issued_by - t_);
    }
    // DRAM: each channel's service of the epoch's bursts, behind its backlog.
    // Only a channel that served a read holds the pipeline (write-backs are
    // posted): it must have served the epoch's reads, so everything queued
    // before them, by the epoch's end.
    std::vector<uint64_t> clock;
    dram_.clocks(clock);
    if (backlog_.empty()) {
      backlog_.assign(clock.size(), 0.0);
      clock_.assign(clock.size(), 0);
    }
    std::vector<double> work(clock.size());
    for (size_t i = 0; i < clock.size(); ++i) {
      work[i] = backlog_[i] + double(clock[i] - clock_[i]);
      if (dram_.take_read(i)) b[int(ApproxBound::kDram)] = std::max(b[int(ApproxBound::kDram)], work[i]);
    }
    clock_ = clock;
    int top = 0;
    for (int i = 0; i < kApproxBounds; ++i) {
      out_.bound_cycles[size_t(i)] += b[size_t(i)];
      if (b[size_t(i)] > b[size_t(top)]) top = i;
    }
    const double d = b[size_t(top)];
    // What a channel could not serve in the epoch's cycles carries over.
    for (size_t i = 0; i < clock.size(); ++i) backlog_[i] = std::max(0.0, work[i] - d);
    out_.limiting_cycles[size_t(top)] += d;
    unit_cycles[size_t(unit_kind)] += b[int(ApproxBound::kUnit)];
    t_ += d;
    ++epochs_;
    in_epoch_ = 0;
    for (auto& e : rops_) e = RopEpoch{};
  }

  const HwConfig& hw_;
  ApproxStats& out_;
  RopOwnership owner_;
  AddressMap amap_;
  DramTags dram_;
  std::unique_ptr<SortAlgorithm> sorter_;
  std::vector<std::unique_ptr<TagOnlyCache>> caches_;
  std::vector<RopEpoch> rops_;
  size_t width_;
  std::vector<double> retire_;                     // per pixel: its last fragment's estimated retirement
  std::vector<std::vector<double>> window_issue_;  // per ROP: the issue cycles of its last `window` fragments
  std::vector<size_t> window_at_;
  std::vector<DepthSlots> slots_;  // per ROP: its depth test in time
  double delivery_rate_ = 1;       // fragments per clock the source and the distributor deliver
  double delivered_ = -1e300;      // the cycle the distributor delivered the last fragment
  bool blend_pass_ = false, tracker_ = false, sorter_on_ = false, reference_on_ = false, tracker_unit_ = false;
  bool slab_ = false, prepass_ = false, color_ = true, trans_ = false, accum_ = false, framebuffer_ = false;
  Buffer marks_ = Buffer::kDepth;  // the target the stochastic pass writes besides depth and colour (kDepth: none)
  uint64_t epoch_ = 1, in_epoch_ = 0, epochs_ = 0, fill_ = 0;
  double t_ = 0;                 // the pipeline's cycles so far (the epochs')
  std::vector<uint64_t> clock_;  // each channel's service clock at the epoch's start
  std::vector<double> backlog_;  // each channel's work not yet served at the epoch's start
  bool first_ = true;
  TagOnlyCompression* comp_;
};

}  // namespace

ApproxRun run_approximate(const InputSpec& in, const GoldenConfig& method, const HwConfig& hw) {
  if (method.method == Method::kReference)
    throw UserError("--method reference has no ROP pipeline: use --fidelity functional");
  if (const char* err = validate(method.numerics)) throw UserError(err);
  validate_hw_config(hw);
  const auto t0 = std::chrono::steady_clock::now();
  ApproxRun run;
  std::unique_ptr<FragmentSource> src = open_fragments(in);
  run.header = src->header();
  // The tag-only model's structures, charged before any is built (memory_estimate.h).
  const MemoryEstimate estimate = estimate_memory(
      hw, MemoryShape{run.header.width, run.header.height, run.header.spp, method.method}, MemoryModel::kApproximate);
  check_model_memory(hw, estimate);
  BudgetShare model_memory;
  model_memory.add(estimate.total_bytes, "the approximate model's structures");
  auto rop = std::make_unique<FunctionalRop>(run.header, on_design(method, hw.compression.setup()));
  ApproxStats& s = run.stats;
  s.hw = hw;
  s.hw.numerics = method.numerics;
  s.hw.blend.formats = target_formats(method);
  if (run_uses_transmittance(method.method, rop->setup().prepass)) s.listed |= 1u << int(Buffer::kTransmittance);
  if (run_uses_accum(method.method, rop->setup().prepass)) s.listed |= 1u << int(Buffer::kAccum);
  if (method.method == Method::kSlab) s.listed |= 1u << int(Buffer::kLayers);
  LineSet in_dram(hw.cache.line_bytes);
  // Surface compression and Hi-Z: the stored state bits, the metadata
  // caches and the Hi-Z bounds outlive the passes, like the lines DRAM holds.
  // The tiles are compressed as the functional store holds them when a line
  // is written back, so the model then runs fragment by fragment with the
  // functional pass (not a batch behind it on another thread).
  std::unique_ptr<StoreTileSource> tiles;
  std::unique_ptr<TagOnlyCompression> comp;
  if (hw.compression.any() || hw.hiz.enable) {
    tiles = std::make_unique<StoreTileSource>(rop->store(), hw.compression.setup().format);
    comp = std::make_unique<TagOnlyCompression>(hw, run.header.width, run.header.height, run.header.spp,
                                                compressed_bytes_per_sample(*rop),
                                                canonical_depth(run.header.clear_depth), *tiles);
    s.compression_on = true;
  }
  std::array<double, kUnitKinds> unit_cycles{};
  // Per ROP and unit kind: its initiation intervals over every pass (the
  // passes run one after another, so they add up).
  std::vector<std::array<double, kUnitKinds>> rop_demand(hw.distributor.rop_units);
  Progress progress("approximate", "fragments");
  uint64_t read = 0;
  for_each_pass(
      *rop, src, [&] { return open_fragments(in); },
      [&](int pass, int passes) {
        Model model(hw, *rop, in_dram, s, comp.get());
        const MethodTraits& mt = rop->traits();
        const bool blend_pass = is_blend_pass(rop->pass());
        // The functional pass fills batches of records; the model (the tag-only
        // caches and DRAM, the epochs) consumes the previous batch on a second
        // thread meanwhile, in order, so the result does not depend on it.
        constexpr size_t kBatch = size_t{1} << 15;
        static_assert(kBatch == kApproxBatchRecords, "memory_estimate.h counts two batches of kApproxBatchRecords");
        std::vector<FragRec> batch, spare;
        batch.reserve(kBatch);
        spare.reserve(kBatch);
        std::future<void> job;
        auto hand_over = [&] {
          if (job.valid()) job.get();
          std::swap(batch, spare);
          batch.clear();
          job = std::async(std::launch::async, [&model, &spare] {
            for (const FragRec& r : spare) model.fragment(r);
          });
        };
        FragWork w;
        Fragment f;
        while (src->next(f)) {
          w.f = &f;
          rop->fetch(w);
          rop->depth().run(w);
          FragRec r;
          r.x = f.x;
          r.y = f.y;
          r.covered = w.covered;
          r.survivors = w.survivors;
          r.m = uint16_t(w.m);
          r.depth_test = !w.draw || w.draw->depth_test;
          if (comp && comp->hiz()) {
            // Which fragments the depth test may reject by Hi-Z (depth_test.cpp):
            // the methods' own test, or a draw testing LESS or LEQUAL (blend's
            // draws and a frame's opaque and blended draws test with their own).
            const bool own_test = method.method == Method::kBlend || w.route != DrawRoute::kMethod;
            r.hiz_test = !own_test ? !w.draw || w.draw->depth_test
                                   : w.draw->depth_test && (w.draw->depth_func == DepthFunc::kLess ||
                                                            w.draw->depth_func == DepthFunc::kLequal);
            float zmin = 1.0f;
            for (uint64_t m = w.covered; m; m &= m - 1) zmin = std::min(zmin, w.z[__builtin_ctzll(m)]);
            r.zmin = zmin;
          }
          if (!w.killed()) {
            if (blend_pass) {
              r.blended = uint16_t(rop->blend().run(w));
            } else {
              if (mt.tracker) rop->track().run(w);
              if (mt.sorter) rop->sort().run(w);
              if (mt.reference) r.hashes = uint16_t(rop->reference().run(w));
              r.examined = uint16_t(rop->write().run(w));
              r.slab_kept = method.method == Method::kSlab && w.slab.kept;
            }
            r.written = rop->pass() == PassKind::kFramebuffer ? w.depth_written : w.written;
            r.route = w.route;
            if (w.draw) r.reads_colour = (blend_pass || w.route != DrawRoute::kMethod) && draw_reads_colour(*w.draw);
            r.depth_write = w.route != DrawRoute::kMethod && w.depth_written != 0;
          }
          if (comp) {  // the model reads the store as it is now
            model.fragment(r);
            if (++read % kBatch == 0) progress.update(pass_progress(pass, passes, src->consumed()), read);
            continue;
          }
          batch.push_back(r);
          if (batch.size() == kBatch) {
            hand_over();
            read += kBatch;
            progress.update(pass_progress(pass, passes, src->consumed()), read);
          }
        }
        if (job.valid()) job.get();
        read += batch.size();
        for (const FragRec& x : batch) model.fragment(x);
        const PassResult p = model.finish();
        s.pipeline_cycles += p.cycles + p.fill;
        s.fill_cycles += p.fill;
        s.flush_cycles += p.flush;
        s.total_cycles += p.cycles + p.fill + p.flush;
        s.epochs += p.epochs;
        s.dram_service_cycles += p.dram_service;
        s.dram_timed_service_cycles += p.dram_timed_service;
        for (int k = 0; k < kUnitKinds; ++k) unit_cycles[size_t(k)] += model.unit_cycles[size_t(k)];
        for (size_t r = 0; r < rop_demand.size(); ++r)
          for (int k = 0; k < kUnitKinds; ++k) rop_demand[r][size_t(k)] += model.rop_demand[r][size_t(k)];
      });
  if (comp) s.compression = comp->stats();
  progress.update(1.0, read);
  progress.finish();
  s.busiest_unit = kUnitNames[std::max_element(unit_cycles.begin(), unit_cycles.end()) - unit_cycles.begin()];
  s.limiting =
      ApproxBound(std::max_element(s.limiting_cycles.begin(), s.limiting_cycles.end()) - s.limiting_cycles.begin());
  // The bottleneck from the model's own bounds, in the cycle model's terms
  // (cycle_bounds): the source's and the distributor's rate bounds, per unit
  // kind the busiest ROP's initiation intervals, and for the DRAM the largest
  // of three lower bounds: the busiest channel's service of all its bursts
  // back to back (reads, write-backs, the flush), its service in the timed
  // service counted as the cycle model counts it (the bank's row switches
  // that the bus cannot hide behind other bursts included), and the DRAM
  // bound of the epochs (each at most its epoch's cycles) plus the final flush.
  std::vector<ResourceBound> bounds = {
      {"trace_source", ResourceBound::Kind::kThroughput, s.bound_cycles[int(ApproxBound::kSource)]},
      {"distributor", ResourceBound::Kind::kThroughput, s.bound_cycles[int(ApproxBound::kDistributor)]}};
  for (int k = 0; k < kUnitKinds; ++k) {
    double most = 0;
    for (const auto& r : rop_demand) most = std::max(most, r[size_t(k)]);
    bounds.push_back({kUnitNames[k], ResourceBound::Kind::kThroughput, most});
  }
  bounds.push_back(
      {"dram", ResourceBound::Kind::kBandwidth,
       std::max({double(s.dram_service_cycles), s.bound_cycles[int(ApproxBound::kDram)] + double(s.flush_cycles),
                 double(s.dram_timed_service_cycles)})});
  s.bottleneck = classify_bottleneck(std::move(bounds), double(s.total_cycles));
  run.counters = rop->counters();
  run.kind_fragments = rop->depth().kind_fragments();
  run.image = rop->resolve();
  run.state_bytes = rop->store().state_bytes();
  run.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return run;
}

}  // namespace ropsim
