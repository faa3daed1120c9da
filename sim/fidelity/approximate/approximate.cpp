#include "sim/fidelity/approximate/approximate.h"

#include <algorithm>
#include <chrono>
#include <functional>
#include <future>
#include <memory>

#include "rtl_models/algo/bits.h"
#include "rtl_models/algo/depth.h"
#include "rtl_models/functional/functional_rop.h"
#include "rtl_models/memory/address_map.h"
#include "rtl_models/memory/cache_tags.h"
#include "rtl_models/memory/line_set.h"
#include "rtl_models/sorter/sort_algorithm.h"
#include "rtl_models/top/memory_estimate.h"
#include "rtl_models/top/store_tile_source.h"
#include "rtl_models/units/rop_ownership.h"
#include "sim/fidelity/approximate/approx_compression.h"
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

// ------------------------------------------------------------ tag-only DRAM

/// The DRAM's address map (dram.h: channel from the interleave granule folded
/// with higher bits, bank from the row) and its row buffers, tag-only; and
/// each channel's bursts served in arrival order, twice:
///  - as fast as the channel can, as Dram::access does for requests that all
///    arrive at once: a burst starts when the data bus is free and its bank
///    is free (plus the row-miss penalty). The clock this keeps per channel
///    (bus_free) is the cycles the channel needs for its bursts so far,
///    whatever the arrival times: a lower bound (the DRAM bound).
///  - timed, by Dram::access's rule for a burst requested at a cycle
///    (set_now: the estimated cycle its fragment entered the depth test): it
///    starts no earlier than its request, its bank (plus the row-miss
///    penalty) and the channel's data bus, behind every burst requested
///    before it -- the posted write-backs and the other ROPs' reads. A
///    read's latency is the cycles from its request to its data: the
///    queueing behind the channel's backlog included. The bursts come in the
///    order the model visits the fragments (input order), so one requested
///    earlier than a burst already served waits behind it.
class DramTags : public BurstSink {
 public:
  explicit DramTags(const HwConfig::Dram& cfg) : cfg_(cfg), map_(cfg), ch_(cfg.channels) {
    for (auto& c : ch_) {
      c.open_row.assign(cfg.banks, ~uint64_t{0});
      c.bank_free.assign(cfg.banks, 0);
      c.timed_bank_free.assign(cfg.banks, 0);
    }
  }
  /// The cycle of the next bursts' request (the timed service).
  void set_now(uint64_t now) { now_ = now; }
  /// One burst of `bytes`, requested at set_now's cycle; returns a read's
  /// latency (the timed service: queueing behind the channel's earlier
  /// bursts, row miss, transfer, the read latency). A burst requested
  /// `after` cycles later (a compressed fill's data after its state bits)
  /// starts no earlier than that; its latency counts from set_now's cycle.
  uint64_t access(uint64_t addr, uint32_t bytes, bool write, Buffer b, uint64_t after) override {
    const DramAddressMap::Place at = map_.place(addr);
    const size_t ch_index = at.channel;
    Channel& c = ch_[ch_index];
    if (!write) c.read = true;
    const uint64_t row = at.row, bank = at.bank;
    uint64_t ready = c.bank_free[bank], penalty = 0;
    if (c.open_row[bank] == row) {
      ++s_.row_hits;
    } else {
      ++s_.row_misses;
      c.open_row[bank] = row;
      penalty = cfg_.row_miss_cycles;
    }
    ready += penalty;
    const uint64_t transfer = ceil_div<uint64_t>(bytes, cfg_.bytes_per_clock);
    const uint64_t start = std::max(ready, c.bus_free);
    c.bus_free = c.bank_free[bank] = start + transfer;
    c.busy += transfer;
    // Timed, as Dram::access: the bank from the request (or its previous
    // burst), the row switch in the bank, then the shared data bus.
    const uint64_t timed_start = std::max(std::max(now_ + after, c.timed_bank_free[bank]) + penalty, c.timed_bus_free);
    // Dram::access's service: from the request (or the previous burst's end)
    // to the end of the transfer.
    c.timed_service += timed_start + transfer - std::max(now_ + after, c.timed_bus_free);
    c.timed_bus_free = c.timed_bank_free[bank] = timed_start + transfer;
    if (write) {
      ++s_.writes;
      s_.bytes_written[size_t(b)] += bytes;
      return 0;
    }
    ++s_.reads;
    s_.bytes_read[size_t(b)] += bytes;
    return timed_start + transfer + cfg_.latency_cycles - now_;
  }
  /// The busiest channel's service clock (cycles).
  uint64_t max_clock() const {
    uint64_t m = 0;
    for (const auto& c : ch_) m = std::max(m, c.bus_free);
    return m;
  }
  /// The channel of a burst address.
  size_t channel_of(uint64_t addr) const { return map_.channel_of(addr); }
  /// Each channel's service clock.
  void clocks(std::vector<uint64_t>& out) const {
    out.resize(ch_.size());
    for (size_t i = 0; i < ch_.size(); ++i) out[i] = ch_[i].bus_free;
  }
  /// The busiest channel's service cycles in the timed service.
  uint64_t max_timed_service() const {
    uint64_t m = 0;
    for (const auto& c : ch_) m = std::max(m, c.timed_service);
    return m;
  }
  uint64_t max_busy() const {
    uint64_t m = 0;
    for (const auto& c : ch_) m = std::max(m, c.busy);
    return m;
  }
  /// Whether channel i served a read since the last call, and forget it.
  bool take_read(size_t i) {
    const bool r = ch_[i].read;
    ch_[i].read = false;
    return r;
  }
  size_t channels() const { return ch_.size(); }
  const DramStats& stats() const { return s_; }

 private:
  HwConfig::Dram cfg_;
  DramAddressMap map_;
  struct Channel {
    uint64_t bus_free = 0, busy = 0;
    uint64_t timed_bus_free = 0;  // the timed service's data bus
    uint64_t timed_service = 0;   // the timed service's cycles, as Dram::access counts them
    bool read = false;            // a read since the last take_reads
    std::vector<uint64_t> open_row, bank_free, timed_bank_free;
  };
  std::vector<Channel> ch_;
  uint64_t now_ = 0;
  DramStats s_;
};

// ------------------------------------------------------------ tag-only cache

/// One ROP cache's tags, as RopCache holds them: the same sets (the same
/// index function), ways, LRU replacement, read-allocate with a fill,
/// write-allocate without one, fast clear from the lines DRAM holds, and the
/// final flush in way order. Its misses and write-backs go to the DRAM model
/// (dram.h: the channel, bank and row map, the row buffers, each channel's
/// bursts served in arrival order) at the cycle the model estimates for the
/// access. With compression (comp), the compressed surfaces' fills and
/// write-backs move their tiles' compressed bytes and the state bits
/// (approx_compression.h), and a dirty line's eviction writes its tile's
/// other dirty lines with it, as RopCache does.
class TagOnlyCache {
 public:
  enum class Read { kHit, kClearFill, kMiss };
  /// window: the depth test's outstanding fragments (depth_test.max_outstanding);
  /// rop: the cache's ROP (its metadata cache).
  TagOnlyCache(const HwConfig::Cache& cfg, uint32_t window, DramTags& dram, LineSet& in_dram, TagOnlyCompression* comp,
               uint32_t rop)
      : window_(window),
        cfg_(cfg),
        dram_(dram),
        in_dram_(in_dram),
        comp_(comp),
        rop_(rop),
        tags_(cfg),
        ways_(tags_.size()) {}

  /// A read; latency: the cycles until its data is there, unloaded.
  Read read(uint64_t line, Buffer b, uint64_t& latency) {
    bool hit = false;
    Way& w = ways_[lookup(line, hit)];
    if (hit) {
      ++s_.read_hits[size_t(b)];
      latency = cfg_.hit_latency_cycles;
      // A hit on a line whose fill is still in flight waits for it (the
      // cache's MSHR merge). The fill is in flight while its fragment waits
      // in the depth test: for the next `window` fragments of this ROP, the
      // k-th of which (entering k / window of a fill's latency later, when
      // the depth test's slots turn over once per fill) waits the rest. Not a
      // fragment of the same pixel: pixel ordering issued it only after the
      // filling fragment retired, its data there.
      const uint64_t k = seq_ - w.fill_seq;
      if (w.fill_seq != kNoFill && k > 0 && k < window_ && w.fill_pixel != pixel_) {
        ++s_.merged;
        latency = std::max<uint64_t>(latency, w.fill_latency * (window_ - k) / window_);
      }
      return Read::kHit;
    }
    ++s_.read_misses[size_t(b)];
    w.buf = b;
    w.dirty = false;
    w.fill_seq = kNoFill;
    if (cfg_.fast_clear && !in_dram_.contains(line)) {
      ++s_.clear_fills;
      latency = cfg_.hit_latency_cycles;
      return Read::kClearFill;
    }
    if (comp_ && comp_->compresses(b))
      latency = comp_->fill(line, b, rop_) + cfg_.hit_latency_cycles;
    else
      latency = dram_.access(line, cfg_.line_bytes, false, b, 0) + cfg_.hit_latency_cycles;
    w.fill_seq = seq_;
    w.fill_latency = uint32_t(latency);
    w.fill_pixel = pixel_;
    return Read::kMiss;
  }
  void write(uint64_t line, Buffer b) {
    bool hit = false;
    Way& w = ways_[lookup(line, hit)];
    if (hit) {
      ++s_.write_hits[size_t(b)];
    } else {
      ++s_.write_misses[size_t(b)];
      w.buf = b;
      w.fill_seq = kNoFill;
    }
    if (!w.dirty) ++s_.dirtied;
    w.dirty = true;
    if (comp_) comp_->touched(line, b);
  }
  void flush() {
    for (size_t i = 0; i < ways_.size(); ++i)
      if (Way& w = ways_[i]; tags_.tag(i) != CacheTags::kInvalid && w.dirty) {
        write_back(tags_.tag(i), w.buf);
        w.dirty = false;
      }
  }
  /// The next fragment of this ROP, at pixel key `pixel` (its reads follow).
  void next_fragment(uint32_t pixel) {
    ++seq_;
    pixel_ = pixel;
  }
  const CacheStats& stats() const { return s_; }

 private:
  static constexpr uint64_t kNoFill = ~uint64_t{0};
  struct Way {
    uint64_t fill_seq = kNoFill;  // the fragment whose read filled it from DRAM
    uint32_t fill_latency = 0;    // that fill's latency
    uint32_t fill_pixel = 0;      // that fragment's pixel
    Buffer buf = Buffer::kDepth;
    bool dirty = false;
  };
  // The cycle model's placement (cache_tags.h); a miss evicts the way's line.
  size_t lookup(uint64_t line, bool& hit) {
    const size_t victim = tags_.find(line, hit);
    if (hit) return victim;
    if (const uint64_t old = tags_.tag(victim); old != CacheTags::kInvalid) {
      ++s_.evictions;
      if (ways_[victim].dirty) {
        ++s_.dirty_evictions;
        const Buffer b = ways_[victim].buf;
        write_back(old, b);
        // A compressed tile leaves as a block: the tile's other dirty lines
        // are written back with it (and stay, clean).
        if (comp_ && comp_->compresses(b)) {
          uint64_t first = 0, count = 0;
          comp_->tile_lines(old, b, first, count);
          for (uint64_t k = 0; k < count; ++k) {
            const uint64_t other = first + k * cfg_.line_bytes;
            if (other == old) continue;
            const size_t ow = tags_.probe(other);
            if (ow == CacheTags::kNone || !ways_[ow].dirty || ways_[ow].buf != b) continue;
            write_back(other, b);
            ways_[ow].dirty = false;
          }
        }
      }
      ways_[victim].dirty = false;
    }
    tags_.install(victim, line);
    return victim;
  }
  /// A dirty line to DRAM: compressed (a cleared tile writes no data and
  /// stays out of DRAM: a later fill is a clear fill), or whole.
  void write_back(uint64_t line, Buffer b) {
    if (comp_ && comp_->compresses(b)) {
      if (comp_->write_back(line, b, rop_)) in_dram_.insert(line);
      return;
    }
    if (comp_ && b == Buffer::kDepth) comp_->depth_written_back(line);  // Hi-Z alone
    dram_.access(line, cfg_.line_bytes, true, b, 0);
    in_dram_.insert(line);
  }
  static_assert(sizeof(Way) == kApproxWayBytes, "memory_estimate.h's kApproxWayBytes is a tag-only way's size");
  uint64_t window_, seq_ = 0;
  uint32_t pixel_ = 0;
  HwConfig::Cache cfg_;
  DramTags& dram_;
  LineSet& in_dram_;
  TagOnlyCompression* comp_;
  uint32_t rop_;
  CacheTags tags_;
  std::vector<Way> ways_;
  CacheStats s_;
};

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
  for (int pass = 0; pass < rop->passes(); ++pass) {
    rop->begin_pass(pass);
    if (pass > 0) src = open_fragments(in);
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
        if (++read % kBatch == 0) progress.update((double(pass) + src->consumed()) / double(rop->passes()), read);
        continue;
      }
      batch.push_back(r);
      if (batch.size() == kBatch) {
        hand_over();
        read += kBatch;
        progress.update((double(pass) + src->consumed()) / double(rop->passes()), read);
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
  }
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
