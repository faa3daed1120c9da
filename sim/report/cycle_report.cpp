#include "sim/report/cycle_report.h"

#include <fmt/format.h>

#include <map>
#include <variant>

#include "sim/image/image_io.h"
#include "util/errors.h"

namespace ropsim {

namespace {

/// The functional part of a timed run (a CycleRun or an ApproxRun), for the
/// functional report and summary it extends.
template <class Run>
FunctionalRun as_functional(const Run& run, const std::optional<Image>& reference) {
  FunctionalRun f;
  f.header = run.header;
  f.counters = run.counters;
  f.kind_fragments = run.kind_fragments;
  f.image = run.image;
  f.state_bytes = run.state_bytes;
  f.wall_seconds = run.wall_seconds;
  f.reference = reference;
  return f;
}

/// A sampled run's functional part: the library's exact counters and image.
FunctionalRun as_functional(const LivePoints& lib, double wall_seconds, const std::optional<Image>& reference) {
  FunctionalRun f;
  f.header = lib.header;
  f.counters = lib.counters;
  f.image = lib.image;
  f.wall_seconds = wall_seconds;
  f.reference = reference;
  return f;
}

const char* activity_meaning(Activity a) {
  switch (a) {
    case Activity::kIdle:
      return "cycles before its first or after its last fragment";
    case Activity::kBusy:
      return "cycles working";
    case Activity::kStarved:
      return "cycles waiting for input";
    case Activity::kBlocked:
      return "cycles waiting for space in the FIFO behind it";
    case Activity::kHazard:
      return "ordering: cycles with every waiting fragment's pixel in flight, or the scoreboard full";
    case Activity::kMemory:
      return "cycles waiting for the ROP cache or DRAM";
  }
  return "";
}

}  // namespace

/// A unit instance's identity (cycle and sampled reports).
static void put_unit_identity(Fields j, const UnitReport& u) {
  j.put("name", u.name, "-", "the unit instance (SystemC name)");
  j.put("kind", u.kind, "-",
        "trace_source, distributor, pixel_ordering, depth_test, coverage_tracker, sample_sorter, "
        "alpha_ref_gen, writeback or blend");
  j.put("rop", u.rop, "-", "the ROP unit it belongs to (-1: shared)");
}

/// A unit instance's cycles per activity (cycle and sampled reports).
static void put_unit_activity(Fields j, const UnitReport& u, uint64_t total_cycles) {
  Fields c = j.obj("cycles");
  for (int a = 0; a < kActivities; ++a)
    c.put(to_string(Activity(a)), u.stats.cycles[size_t(a)], "cycles",
          std::string(activity_meaning(Activity(a))) + " (the activities sum to total_cycles)");
  const uint64_t busy = u.stats.cycles[size_t(Activity::kBusy)];
  j.put("busy_fraction", total_cycles ? double(busy) / double(total_cycles) : 0.0, "fraction",
        "busy cycles / total_cycles");
}

/// The ROP caches' figures, summed over the ROPs (cycle and approximate reports).
static void put_cache_stats(Fields cache, const CacheStats& sum, uint32_t listed) {
  for (int b = 0; b < kBuffers; ++b) {
    if (!((listed >> b) & 1u)) continue;
    const size_t i = size_t(b);
    const std::string buf = to_string(Buffer(b));
    Fields x = cache.obj(buf);
    x.put("read_hits", sum.read_hits[i], "accesses", buf + " line reads that hit, over the ROP caches");
    x.put("read_misses", sum.read_misses[i], "accesses", buf + " line reads that missed");
    x.put("write_hits", sum.write_hits[i], "accesses", buf + " line writes that hit");
    x.put("write_misses", sum.write_misses[i], "accesses", buf + " line writes that missed (allocated without a fill)");
  }
  cache.put("hits", sum.hits(), "accesses", "read and write hits over every buffer");
  cache.put("misses", sum.misses(), "accesses", "read and write misses over every buffer");
  cache.put("hit_rate", sum.hit_rate(), "fraction", "hits / (hits + misses)");
  cache.put("merged_reads", sum.merged, "accesses", "reads of a line whose fill was in flight");
  cache.put("evictions", sum.evictions, "lines", "lines evicted");
  cache.put("dirty_evictions", sum.dirty_evictions, "lines", "dirty lines evicted (written to DRAM)");
  cache.put("fast_clear_fills", sum.clear_fills, "accesses", "misses served as the clear value, without DRAM");
}

/// The DRAM's bytes per buffer and in all, its bursts and row hits (cycle
/// and approximate reports).
static void put_dram_traffic(Fields dram, const DramStats& d, uint32_t listed) {
  for (int b = 0; b < kBuffers; ++b) {
    if (!((listed >> b) & 1u)) continue;
    const std::string buf = to_string(Buffer(b));
    Fields x = dram.obj(buf);
    x.put("bytes_read", d.bytes_read[size_t(b)], "bytes",
          "DRAM bytes read for the " + buf + " buffer (line-sized bursts)");
    x.put("bytes_written", d.bytes_written[size_t(b)], "bytes", "DRAM bytes written for the " + buf + " buffer");
  }
  dram.put("bytes_read", d.total_bytes_read(), "bytes", "DRAM bytes read, every buffer");
  dram.put("bytes_written", d.total_bytes_written(), "bytes", "DRAM bytes written, every buffer");
  dram.put("reads", d.reads, "bursts", "read bursts");
  dram.put("writes", d.writes, "bursts", "write bursts");
  dram.put("row_hits", d.row_hits, "bursts", "bursts to the open row");
  dram.put("row_misses", d.row_misses, "bursts", "bursts that opened a row");
}

/// Surface compression's traffic and Hi-Z (compression_model.h; the
/// approximate model's approx_compression.h counts the same): per
/// compressed surface, its line transfers' bytes before and after
/// compression, the block sizes of the tiles written, and its state bits'
/// traffic (included in the DRAM bytes of the surface).
static void put_compression_traffic(Fields c, const CompressionTraffic& s, const HwConfig& hw) {
  c.put("depth", hw.compression.depth, "-", "compression.depth: depth plane compression on");
  c.put("color", hw.compression.color, "-", "compression.color: colour (and blend-target) compression on");
  c.put("hiz", hw.hiz.enable, "-", "hiz.enable: hierarchical Z on");
  c.put("metadata_hits", s.metadata_hits, "accesses", "state-bit lookups that hit the ROPs' metadata caches");
  c.put("metadata_misses", s.metadata_misses, "accesses", "state-bit lookups that read a metadata line from DRAM");
  c.put("hiz_tests", s.hiz_tests, "fragments", "fragments tested against their tile's Hi-Z bound");
  c.put("hiz_rejected", s.hiz_rejected, "fragments",
        "fragments rejected by Hi-Z: every tested sample beyond the tile's farthest depth, no depth read");
  c.put("hiz_depth_lines_skipped", s.hiz_lines_skipped, "lines", "depth lines the rejected fragments did not read");
  c.empty_array("buffers");
  for (int b = 0; b < kBuffers; ++b) {
    if (!s.lines_written[size_t(b)] && !s.lines_read[size_t(b)] && !s.metadata_bytes_read[size_t(b)]) continue;
    Fields e = c.item("buffers");
    e.put("buffer", to_string(Buffer(b)), "-", "the compressed surface");
    e.put("bytes_written_uncompressed", s.bytes_written_uncompressed[size_t(b)], "bytes",
          "line writebacks to DRAM at their uncompressed size (line_bytes each)");
    e.put("bytes_written", s.bytes_written[size_t(b)], "bytes",
          "the same compressed: line_bytes >> the block-size class of the line's tile (0 for a cleared tile)");
    e.put("bytes_read_uncompressed", s.bytes_read_uncompressed[size_t(b)], "bytes",
          "line fills from DRAM at their uncompressed size");
    e.put("bytes_read", s.bytes_read[size_t(b)], "bytes",
          "the same compressed, as stored at the tile's last writeback");
    const auto& wc = s.writes_per_class[size_t(b)];
    const uint64_t n = s.lines_written[size_t(b)];
    std::vector<uint64_t> per(wc.begin(), wc.begin() + hw.compression.size_classes);
    std::vector<double> share;
    for (uint64_t k : per) share.push_back(n ? double(k) / double(n) : 0.0);
    e.put("writes_per_class", per, "lines",
          "[j]: line writebacks whose tile was stored in U / 2^j bytes (j = 0: uncompressed)");
    e.put("class_shares", share, "-", "the same as shares of all the surface's line writebacks");
    e.put("writes_cleared", s.writes_cleared[size_t(b)], "lines",
          "line writebacks of tiles holding only the clear value (state bits only)");
    e.put("metadata_bytes_read", s.metadata_bytes_read[size_t(b)], "bytes", "state-bit lines read from DRAM");
    e.put("metadata_bytes_written", s.metadata_bytes_written[size_t(b)], "bytes", "state-bit lines written to DRAM");
  }
}

/// The summary's line on compression and Hi-Z (cycle and approximate).
static std::string compression_summary(const CompressionTraffic& c) {
  uint64_t before = 0, after = 0;
  for (size_t b = 0; b < size_t(kBuffers); ++b) {
    before += c.bytes_written_uncompressed[b] + c.bytes_read_uncompressed[b];
    after += c.bytes_written[b] + c.bytes_read[b];
  }
  return fmt::format(
      "  compression: {} B of compressed-surface traffic moved as {} B; Hi-Z rejected {} of {} fragments\n", before,
      after, c.hiz_rejected, c.hiz_tests);
}

RtlDesign rtl_design_of(const HwConfig& hw) {
  RtlDesign d;
  d.name = hw.name;
  d.rop_units = int(hw.distributor.rop_units);
  d.alpha_ref_lanes = int(hw.alpha_ref.lanes);
  d.alpha_ref_stages = int(hw.alpha_ref.pipeline_depth);
  d.depth_lanes = int(hw.depth_test.samples_per_clock);
  d.depth_stages = int(hw.depth_test.latency_cycles);
  d.tracker_stages = int(hw.tracker.latency_cycles);
  d.opacity_lanes = int(hw.writeback.samples_per_clock);
  d.sorter_kind = to_string(hw.sorter.kind);
  d.numerics = hw.numerics;
  return d;
}

ReportContext with_design(const ReportContext& ctx, const HwConfig& hw) {
  ReportContext c = ctx;
  c.design = rtl_design_of(hw);
  return c;
}

std::string format_bottleneck(const CycleStats& s) { return format_bottleneck(s.bottleneck); }

namespace {
/// timing.bottleneck*: the class and its line, and every bound beside it.
void put_bottleneck(Fields t, const Bottleneck& b) {
  t.put("bottleneck", format_bottleneck(b), "-",
        "one line \"CLASS: why\": throughput (UNIT) or bandwidth (dram) when that resource's bound is >= 80 % of "
        "total_cycles, the largest bound; else latency (docs/reports.md \"The bottleneck\")");
  t.put("bottleneck_kind", to_string(b.kind), "-", "throughput, bandwidth or latency (the class of bottleneck)");
  t.empty_array("bottleneck_bounds");
  for (const ResourceBound& r : b.bounds) {
    Fields j = t.item("bottleneck_bounds");
    j.put("resource", r.name, "-", "a unit kind (throughput) or dram (bandwidth); largest bound first");
    j.put("kind", to_string(r.kind), "-", "throughput (a unit) or bandwidth (the DRAM)");
    j.put(
        "cycles", r.cycles, "cycles",
        "the resource's own lower bound on the frame: a unit kind's busy cycles in its busiest instance (approximate: "
        "the initiation intervals of its busiest ROP), the DRAM's busiest channel's service cycles (approximate: the "
        "largest of its bursts served back to back, its service in the timed DRAM and bound_cycles.dram + "
        "flush_cycles; docs/reports.md \"The bottleneck\")");
    j.put("frame_share", b.frame_cycles > 0 ? r.cycles / b.frame_cycles : 0.0, "fraction",
          "cycles / total_cycles: at least 0.8 bounds the frame");
  }
}

}  // namespace

void put_cycle_stats(Fields t, const CycleStats& s) {
  t.put("clock_ghz", s.hw.clock.frequency_ghz, "GHz", "the ROP clock");
  t.put("clock_period_ps", s.period_ps, "ps", "the simulated clock period (1000 / GHz, rounded)");
  t.put("total_cycles", s.total_cycles, "cycles", "to the end of the final cache flush");
  t.put("pipeline_cycles", s.pipeline_cycles, "cycles", "to the retirement of the last fragment");
  t.put("frame_time_us", s.frame_time_us, "µs", "total_cycles at the clock");
  t.put("fragments_per_clock", s.fragments_per_clock, "1/clock", "fragments over total_cycles");
  t.put("samples_per_clock", s.samples_per_clock, "1/clock", "covered samples over total_cycles");
  put_bottleneck(t, s.bottleneck);
  t.put("memory_bound", s.memory_bound, "bool", "the bottleneck is the DRAM's bandwidth (bottleneck_kind)");
  t.empty_array("units");
  for (const auto& u : s.units) {
    Fields j = t.item("units");
    put_unit_identity(j, u);
    j.put("fragments", u.stats.fragments, "fragments", "fragments it accepted");
    j.put("samples", u.stats.samples, "samples",
          "unit-specific: tested (depth test), tracked, sorted, hashed (alpha-ref gen), examined (writeback)");
    put_unit_activity(j, u, s.total_cycles);
    j.put("activations", u.stats.activations, "-",
          "times the scheduler ran the unit (0 for a decoupled unit, which runs inside its neighbours' runs)");
    for (const auto& e : u.extras) j.put(e.name, e.value, e.unit, u.kind + ": " + e.meaning);
  }
  t.empty_array("fifos");
  for (const auto& f : s.fifos) {
    Fields j = t.item("fifos");
    j.put("name", f.name, "-", "the FIFO (producer to consumer)");
    j.put("capacity_entries", f.capacity, "entries", "its depth plus the producer's latency (pipeline registers)");
    j.put("pushes", f.pushes, "entries", "entries pushed");
    j.put("mean_occupancy_entries", f.mean_occupancy, "entries", "time-averaged occupancy");
    j.put("max_occupancy_entries", f.max_occupancy, "entries", "largest occupancy");
    j.put("full_cycles", f.full_cycles, "cycles", "cycles at capacity");
  }
  // Caches: the sum over the ROPs.
  CacheStats sum;
  for (const auto& c : s.caches) sum += c;
  put_cache_stats(t.obj("cache"), sum, s.listed);
  Fields dram = t.obj("dram");
  put_dram_traffic(dram, s.dram, s.listed);
  dram.put("peak_gbps", s.dram_peak_gbps, "GB/s", "channels x bytes/clock x GHz (GB/s = 10^9 B/s)");
  dram.put("achieved_gbps", s.dram_achieved_gbps, "GB/s", "bytes moved / frame time");
  dram.put("busiest_channel_utilization", s.dram_utilization, "fraction",
           "data-bus busy cycles of the busiest channel / total_cycles");
  if (s.compression_on) put_compression_traffic(t.obj("compression"), s.compression, s.hw);
  // Multi-pass methods: each pass's cycles and traffic (single-pass methods have none).
  if (!s.passes.empty()) {
    t.empty_array("passes");
    for (const auto& p : s.passes) {
      Fields j = t.item("passes");
      j.put("name", p.name, "-", "multi-pass methods: the pass (total_alpha, stochastic, accumulate)");
      j.put("total_cycles", p.total_cycles, "cycles", "the pass, to the end of its cache flush");
      j.put("pipeline_cycles", p.pipeline_cycles, "cycles", "the pass, to its last retirement");
      j.put("cache_hits", p.cache.hits(), "accesses", "the pass's cache hits over every buffer and ROP");
      j.put("cache_misses", p.cache.misses(), "accesses", "the pass's cache misses over every buffer and ROP");
      Fields d = j.obj("dram");
      for (int b = 0; b < kBuffers; ++b) {
        if (!s.lists(b)) continue;
        const std::string buf = to_string(Buffer(b));
        Fields x = d.obj(buf);
        x.put("bytes_read", p.dram.bytes_read[size_t(b)], "bytes",
              "the pass's DRAM bytes read for the " + buf + " buffer");
        x.put("bytes_written", p.dram.bytes_written[size_t(b)], "bytes",
              "the pass's DRAM bytes written for the " + buf + " buffer");
      }
      d.put("bytes_read", p.dram.total_bytes_read(), "bytes", "the pass's DRAM bytes read, every buffer");
      d.put("bytes_written", p.dram.total_bytes_written(), "bytes", "the pass's DRAM bytes written, every buffer");
    }
  }
  Fields host = t.obj("host");
  host.put("systemc_activations", s.activations, "-",
           "SystemC process activations: cycles in which some unit ran (rtl_models/core/scheduler.h)");
  host.put("unit_runs", s.unit_runs, "-", "the units' runs summed (host cost of event-driven simulation)");
  host.put("decoupled", s.decoupled, "bool",
           "the units without timed shared state ran ahead of SystemC time (false with --lockstep; a --vcd run stays "
           "decoupled)");
  host.put("fragment_tokens", s.tokens_allocated, "-", "fragment records allocated (bounded by FIFOs and windows)");
}

void put_hw_resolved(Fields f, const HwConfig& hw, const std::string& prefix) {
  for_each_hw_value(hw, [&](const ParamInfo& p, const HwValue& v) {
    const auto dot = p.key.find('.');
    Fields sec = f.obj(p.key.substr(0, dot));
    const std::string key = p.key.substr(dot + 1), meaning = prefix + p.meaning;
    std::visit([&](const auto& x) { sec.put(key, x, p.unit, meaning); }, v);
  });
}

nlohmann::ordered_json hw_config_to_json(const HwConfig& hw) {
  nlohmann::ordered_json j;
  put_hw_resolved(Fields(j, nullptr), hw);
  return j;
}

nlohmann::ordered_json cycle_stats_to_json(const CycleStats& s) {
  nlohmann::ordered_json t;
  put_cycle_stats(Fields(t, nullptr), s);
  return t;
}

namespace {
void put_hardware(Fields hw, const HwConfig& c) {
  hw.put("config", c.name, "-", "cycle: the design file (or \"built-in defaults\"), \"with --hw-set\" when overridden");
  hw.put("resolved_toml", hw_config_to_toml(c), "-", "cycle: every hardware parameter as simulated, as TOML");
  hw.put("overrides", c.overrides, "-",
         "cycle: the --hw-set assignments applied over the design file, in order, as given");
  hw.put("digest", hw_digest_hex(c), "-",
         "cycle: 8 hex digits of FNV-1a 64 over the resolved design (in default output names: -hwDIGEST)");
  // Each parameter's unit and meaning come from the parameter table (hw_params()).
  put_hw_resolved(hw.obj("resolved"), c, "cycle: ");
}
}  // namespace

namespace {
void put_approx_stats(Fields t, const ApproxStats& s, const Counters& c) {
  const double total = double(std::max<uint64_t>(1, s.total_cycles));
  t.put("clock_ghz", s.hw.clock.frequency_ghz, "GHz", "the ROP clock");
  t.put("total_cycles", s.total_cycles, "cycles", "to the end of the final cache flush");
  t.put("pipeline_cycles", s.pipeline_cycles, "cycles", "to the retirement of the last fragment");
  t.put("frame_time_us", double(s.total_cycles) / (s.hw.clock.frequency_ghz * 1e3), "µs", "total_cycles at the clock");
  t.put("fragments_per_clock", double(c.fragments) / total, "1/clock", "fragments over total_cycles");
  t.put("samples_per_clock", double(c.samples_tested) / total, "1/clock", "covered samples over total_cycles");
  put_bottleneck(t, s.bottleneck);
  put_cache_stats(t.obj("cache"), s.cache, s.listed);
  Fields dram = t.obj("dram");
  put_dram_traffic(dram, s.dram, s.listed);
  dram.put("busiest_channel_utilization", double(s.dram.max_channel_busy) / total, "fraction",
           "data-bus busy cycles of the busiest channel / total_cycles");
  if (s.compression_on) put_compression_traffic(t.obj("compression"), s.compression, s.hw);
  Fields a = t.obj("approximate");
  a.put("epochs", s.epochs, "epochs",
        "approximate: spans of the input whose bounds are taken together (summed over the passes)");
  a.put("epoch_fragments", s.epoch_fragments, "fragments",
        "approximate: fragments per epoch: the ROP units x the fragments queued in one ROP ahead of its depth test's "
        "data (distributor FIFO and latency, ordering window, FIFO and latency, depth-test outstanding)");
  a.put("fill_cycles", s.fill_cycles, "cycles",
        "approximate: the first fragment's trip through the empty pipeline (source, distributor, its units' "
        "latencies), per pass");
  a.put("flush_cycles", s.flush_cycles, "cycles",
        "approximate: the final cache flush: its bursts behind the channels' backlog, beyond the pipeline's drain "
        "(summed over the passes)");
  Fields bc = a.obj("bound_cycles");
  Fields lc = a.obj("limiting_cycles");
  static const char* kMeaning[kApproxBounds] = {
      "fragments / source.fragments_per_clock",
      "fragments / distributor.fragments_per_clock",
      "the busiest unit of the busiest ROP: its initiation intervals summed (pixel ordering 1, depth test "
      "ceil(covered / samples_per_clock), tracker 1, sorter its interval, alpha-ref ceil(hashes / lanes), writeback "
      "ceil(examined / samples_per_clock), blend ceil(blended / samples_per_clock))",
      "the busiest ROP's depth test: each fragment's wait for its pixel's data (hit latency; or the DRAM's row "
      "miss, transfer and read latency) summed / depth_test.max_outstanding",
      "the busiest ROP's pixel ordering: each fragment's unloaded trip from issue to retirement summed / "
      "ordering.pixels_in_flight",
      "the busiest DRAM channel that served a read in the epoch: its bursts served in order, each when the data bus "
      "and its bank are free (plus row_miss_cycles on a row miss), behind the work it carried over from earlier "
      "epochs",
      "the busiest ROP's pixel ordering: the cycle after its last issue, each fragment issued once its pixel's "
      "previous fragment retired (its unloaded trip) and the fragment ordering.window before it left the window"};
  for (int b = 0; b < kApproxBounds; ++b) {
    const std::string name = to_string(ApproxBound(b));
    bc.put(name, s.bound_cycles[size_t(b)], "cycles",
           std::string("approximate: summed over the epochs: ") + kMeaning[b]);
    lc.put(name, s.limiting_cycles[size_t(b)], "cycles",
           "approximate: the cycles of the epochs in which the " + name + " bound was the largest");
  }
  a.put("limiting_bound", to_string(s.limiting), "-",
        "approximate: the bound that was the largest over the most cycles (source, distributor, unit, latency, "
        "scoreboard, dram, hazard)");
  a.put("busiest_unit", s.busiest_unit, "-", "approximate: the unit kind whose demand made most of the unit bound");
}
}  // namespace

nlohmann::ordered_json cycle_report(const ReportContext& ctx, const CycleRun& run,
                                    const std::optional<Image>& reference, FieldSink* sink) {
  nlohmann::ordered_json j = functional_report(with_design(ctx, run.stats.hw), as_functional(run, reference), sink);
  Fields r(j, sink);
  r.put("fidelity", "cycle", "-", kFidelityMeaning);
  put_hardware(r.obj("hardware"), run.stats.hw);
  put_cycle_stats(r.obj("timing"), run.stats);
  Fields host = r.obj("host");
  host.put("sim_seconds", run.sim_seconds, "s", "cycle: sc_start alone");
  host.put("simulated_fragments_per_second",
           run.sim_seconds > 0 ? double(run.counters.fragments) / run.sim_seconds : 0.0, "1/s",
           "cycle: fragments over sim_seconds");
  if (run.breakdown && run.breakdown->per_draw())
    put_draws(r, *run.breakdown, true, has_blend_pass(ctx.config.method) || !run.header.draws.empty(),
              ctx.config.method == Method::kSlab, run.stats.listed);
  return j;
}

nlohmann::ordered_json sampled_report(const ReportContext& ctx, const LivePoints& lib, const SampledRun& s,
                                      const HwConfig& hw, double wall_seconds, const LibrarySource& from,
                                      const std::optional<Image>& reference, FieldSink* sink) {
  nlohmann::ordered_json j = functional_report(with_design(ctx, hw), as_functional(lib, wall_seconds, reference), sink);
  Fields r(j, sink);
  r.put("fidelity", "sampled", "-", kFidelityMeaning);
  put_hardware(r.obj("hardware"), hw);
  Fields t = r.obj("timing");
  auto ci = [](const Estimate& e) { return std::vector<double>{e.low, e.high}; };
  t.put("total_cycles", s.total_cycles.value, "cycles",
        "sampled: estimate of the cycles to the end of the final cache flush (N x the units' mean per fragment, plus "
        "the last unit's drain and flush)");
  t.put("total_cycles_ci95", ci(s.total_cycles), "cycles",
        "sampled: 95 % confidence interval [low, high] of total_cycles (Student t over the units)");
  t.put("frame_time_us", s.total_cycles.value / (hw.clock.frequency_ghz * 1e3), "us",
        "sampled: total_cycles at the configured clock");
  Fields d = t.obj("dram");
  d.put("bytes_read", s.dram_bytes_read.value, "bytes", "sampled: estimate of the DRAM bytes read, every buffer");
  d.put("bytes_read_ci95", ci(s.dram_bytes_read), "bytes", "sampled: its 95 % confidence interval [low, high]");
  d.put("bytes_written", s.dram_bytes_written.value, "bytes",
        "sampled: estimate of the DRAM bytes written, every buffer (the units' lines made dirty, each written once)");
  d.put("bytes_written_ci95", ci(s.dram_bytes_written), "bytes", "sampled: its 95 % confidence interval [low, high]");
  // Compression and Hi-Z: the units' counts per fragment times N (writes: by
  // the lines the windows made dirty), as the cycle model reports them.
  if (s.stats.compression_on) put_compression_traffic(t.obj("compression"), s.stats.compression, hw);
  put_bottleneck(t, s.stats.bottleneck);
  t.put("memory_bound", s.stats.memory_bound, "bool", "the bottleneck is the DRAM's bandwidth (bottleneck_kind)");
  t.empty_array("units");
  for (const auto& u : s.stats.units) {
    Fields j = t.item("units");
    put_unit_identity(j, u);
    put_unit_activity(j, u, s.stats.total_cycles);
  }
  Fields sp = t.obj("sampling");
  sp.put("library", from.path.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(from.path), "-",
         "sampled: the live-point library file read (ropsim livepoints), or null when this run recorded its own");
  sp.put(
      "input_digest", fmt::format("{:016x}", lib.input.digest), "-",
      "sampled: XXH3-64 of the input the live-points were recorded from (a trace file's bytes, a scene's fragments)");
  sp.put("whole", lib.whole, "bool",
         "sampled: the input was small (its units would have simulated at least half of it in detail), so one unit "
         "simulated it whole: the figures are the full cycle run's, exactly");
  sp.put("units", s.units, "units", "sampled: sampling units simulated in detail (K)");
  sp.put("unit_fragments", lib.params.unit_fragments, "fragments", "sampled: fragments per measured window (U)");
  sp.put("warmup_fragments", lib.params.warmup_fragments, "fragments",
         "sampled: fragments simulated in detail before each window (W, at most)");
  sp.put("cooldown_fragments", lib.params.cooldown_fragments, "fragments",
         "sampled: fragments simulated after each window but the last (C)");
  sp.put("warming_fragments", lib.params.warming_fragments, "fragments",
         "sampled: fragments before each warm-up warming the caches tag-only (T, at most)");
  sp.put("warming_reach", lib.params.warming_reach, "x cache lines",
         "sampled: per design, the warming starts where the touches before the warm-up reach R times the design's "
         "cache lines in distinct lines (R)");
  sp.put("fragments_warmed", s.fragments_warmed, "fragments",
         "sampled: fragments whose touches warmed the caches tag-only, summed over the units (this design)");
  sp.put("units_warming_short", s.units_warming_short, "units",
         "sampled: units whose warming stopped at T before reaching R x the cache lines (a larger T would warm "
         "them more)");
  sp.put("fragments", lib.fragments, "fragments", "sampled: the input's fragments (N)");
  sp.put("fragments_detailed", s.fragments_detailed, "fragments",
         "sampled: fragments the cycle model simulated (warm-ups, windows, cool-downs)");
  Fields host = r.obj("host");
  host.put("sampled_seconds", s.sim_seconds, "s",
           "sampled: the units' simulation, tag-only warming included (wall clock, with the workers)");
  host.put("sampled_cpu_seconds", s.cpu_seconds, "s",
           "sampled: the units' simulation, CPU time summed over this process and its workers");
  host.put("sampled_jobs", s.jobs, "processes", "sampled: worker processes that simulated the units (-j)");
  host.put("library_seconds", from.seconds, "s",
           "sampled: recording the live-points (one functional pass), or reading the library file");
  return j;
}

std::string sampled_summary(const ReportContext& ctx, const LivePoints& lib, const SampledRun& s, const HwConfig& hw,
                            double wall_seconds, const LibrarySource& from, const std::optional<Image>& reference) {
  std::string out =
      fmt::format("ropsim: {} | method {} | {}x{} @ {} spp | sampled on {}\n", ctx.input.describe(),
                  to_string(ctx.config.method), lib.header.width, lib.header.height, lib.header.spp, hw.name);
  auto line = [](const char* what, const Estimate& e, const char* unit) {
    return fmt::format("  {:<14} {:.0f} {} (95 % interval {:.0f} .. {:.0f}, +-{:.2f} %)\n", what, e.value, unit, e.low,
                       e.high, e.value > 0 ? 50.0 * (e.high - e.low) / e.value : 0.0);
  };
  out += line("total cycles", s.total_cycles, "cycles");
  out += line("DRAM read", s.dram_bytes_read, "bytes");
  out += line("DRAM written", s.dram_bytes_written, "bytes");
  if (s.stats.compression_on) {
    const CompressionTraffic& c = s.stats.compression;
    uint64_t before = 0, after = 0;
    for (size_t b = 0; b < size_t(kBuffers); ++b) {
      before += c.bytes_written_uncompressed[b] + c.bytes_read_uncompressed[b];
      after += c.bytes_written[b] + c.bytes_read[b];
    }
    out += fmt::format(
        "  compression (estimated): {} B of compressed-surface traffic moved as {} B; Hi-Z rejected {} of {} "
        "fragments\n",
        before, after, c.hiz_rejected, c.hiz_tests);
  }
  out += fmt::format("  {} units of {} fragments; {} of {} fragments simulated in detail ({:.1f} %)\n", s.units,
                     lib.params.unit_fragments, s.fragments_detailed, lib.fragments,
                     lib.fragments ? 100.0 * double(s.fragments_detailed) / double(lib.fragments) : 0.0);
  out += "  " + format_bottleneck(s.stats) + " (estimated)\n";
  out += "  bounds (cycles, estimated): " + format_bounds(s.stats.bottleneck) + "\n";
  if (reference) {
    const CompareResult cr = compare_images(lib.image, *reference);
    out += fmt::format("  vs reference: RMSE {:.3f} (8-bit units), PSNR {:.2f} dB\n", cr.rmse_8bit, cr.psnr_db);
  }
  out += fmt::format("  wall {:.3f} s ({} {:.3f} s, units {:.3f} s on {} process{})\n", wall_seconds,
                     from.path.empty() ? "live-points recorded in" : "library " + from.path + " read in", from.seconds,
                     s.sim_seconds, s.jobs, s.jobs == 1 ? "" : "es");
  for (const auto& o : ctx.outputs) out += "  wrote " + o + "\n";
  return out;
}

nlohmann::ordered_json approximate_report(const ReportContext& ctx, const ApproxRun& run,
                                          const std::optional<Image>& reference, FieldSink* sink) {
  nlohmann::ordered_json j = functional_report(with_design(ctx, run.stats.hw), as_functional(run, reference), sink);
  Fields r(j, sink);
  r.put("fidelity", "approximate", "-", kFidelityMeaning);
  const ApproxStats& s = run.stats;
  put_hardware(r.obj("hardware"), s.hw);
  put_approx_stats(r.obj("timing"), s, run.counters);
  return j;
}

std::string approximate_summary(const ReportContext& ctx, const ApproxRun& run, const std::optional<Image>& reference) {
  const ApproxStats& s = run.stats;
  std::string out = functional_summary(ctx, as_functional(run, reference));
  out += fmt::format("  approximate model ({}): {} cycles = {:.2f} us at {} GHz ({} in epochs, fill {}, flush {})\n",
                     s.hw.name, s.total_cycles, double(s.total_cycles) / (s.hw.clock.frequency_ghz * 1e3),
                     s.hw.clock.frequency_ghz, s.total_cycles - s.fill_cycles - s.flush_cycles, s.fill_cycles,
                     s.flush_cycles);
  out += fmt::format("  DRAM: {} B read, {} B written (tag-only)\n", s.dram.total_bytes_read(),
                     s.dram.total_bytes_written());
  if (s.compression_on) out += compression_summary(s.compression);
  std::string bounds;
  for (int b = 0; b < kApproxBounds; ++b)
    bounds += fmt::format("{}{} {:.0f}", b ? ", " : "", to_string(ApproxBound(b)), s.bound_cycles[size_t(b)]);
  out += "  model bounds (cycles, summed over the epochs): " + bounds + "\n";
  out += "  " + format_bottleneck(s.bottleneck) + "\n";
  out += "  bounds (cycles): " + format_bounds(s.bottleneck) + "\n";
  return out;
}

std::vector<FieldDoc> report_field_docs() {
  // The fields are described where they are written, so list them by writing
  // the reports of small runs that emit every field: lk (every unit) on a
  // scene, with the reference; a trace input's fields come from the context.
  FieldSink sink;
  InputSpec in;
  in.scene.name = "eight-layers";
  in.scene.spp = 4;
  in.scene.width = 16;
  in.scene.height = 16;
  MethodConfig m;
  ReportContext ctx;
  ctx.command_line = "ropsim run ...";
  ctx.input = in;
  ctx.config = m;
  ctx.design = rtl_design_of(HwConfig{});
  const FunctionalRun f = run_functional(in, m, true, 0, BreakdownRequest{true, false});
  {  // the compressibility fields: the same run with every surface compressed
    MethodConfig mc = m;
    mc.compression = HwConfig{}.compression.setup();
    mc.compression.depth = mc.compression.color = true;
    ReportContext cc = ctx;
    cc.config = mc;
    functional_report(cc, run_functional(in, mc, false), &sink);
  }
  functional_report(ctx, f, &sink);
  {  // a frame of draw states: its draw kinds (the fields do not depend on the values)
    FunctionalRun d = run_functional(in, m, false);
    d.header.draws = DrawTable({default_draw_state(0)});
    d.kind_fragments[size_t(DrawKind::kSrcOver)] = d.counters.fragments;
    ReportContext dc = ctx;
    dc.frame = FrameStats{};
    functional_report(dc, d, &sink);
  }
  CycleOptions with_draws;
  with_draws.breakdown.per_draw = true;
  const CycleRun c = run_cycle(in, m, HwConfig{}, with_draws);
  ctx.input.trace_path = "scene.rtr";
  cycle_report(ctx, c, f.reference, &sink);
  {  // compression and Hi-Z (the cycle model's traffic)
    HwConfig hc;
    hc.compression.depth = hc.compression.color = hc.hiz.enable = true;
    MethodConfig mc = m;
    mc.compression = hc.compression.setup();
    ReportContext cc = ctx;
    cc.config = mc;
    cycle_report(cc, run_cycle(in, mc, hc), f.reference, &sink);
  }
  // The fields only some methods write (the hashed coverage selection's,
  // slab's parameters and layers buffer).
  m.method = Method::kSlab;
  ctx.config = m;
  cycle_report(ctx, run_cycle(in, m, HwConfig{}, with_draws), f.reference, &sink);  // and its per-draw DRAM
  // A method with every kind of blend pass and render target: passes, targets,
  // the blend counters and unit.
  ctx.input.trace_path.clear();
  for (Method bm : {Method::kLkDepthAc, Method::kWboit, Method::kEndertonAc}) {
    ctx.config.method = m.method = bm;
    const FunctionalRun fb = run_functional(in, m, false);
    functional_report(ctx, fb, &sink);
    const CycleRun cb = run_cycle(in, m, HwConfig{}, with_draws);
    cycle_report(ctx, cb, std::nullopt, &sink);
  }
  // A sampled run's fields.
  {
    SamplingParams sp;
    sp.units = 2;
    sp.unit_fragments = 16;
    sp.warmup_fragments = 8;
    sp.cooldown_fragments = 8;
    sp.warming_fragments = 8;
    ctx.config = MethodConfig{};
    const LivePoints lib = record_livepoints(in, ctx.config, sp);
    sampled_report(ctx, lib, run_sampled(lib, HwConfig{}), HwConfig{}, 0.0, LibrarySource{"lib.rlp", 0.0}, std::nullopt,
                   &sink);
  }
  // An approximate run's fields (its method's buffers as above).
  ctx.config = MethodConfig{};
  approximate_report(ctx, run_approximate(in, ctx.config, HwConfig{}), std::nullopt, &sink);
  {  // with compression and Hi-Z (the same fields as the cycle model's)
    HwConfig hc;
    hc.compression.depth = hc.compression.color = hc.hiz.enable = true;
    ReportContext cc = ctx;
    cc.config.compression = hc.compression.setup();
    approximate_report(cc, run_approximate(in, cc.config, hc), std::nullopt, &sink);
  }
  return sink.docs();
}

std::string cycle_summary(const ReportContext& ctx, const CycleRun& run, const std::optional<Image>& reference) {
  const CycleStats& s = run.stats;
  std::string out = functional_summary(ctx, as_functional(run, reference));
  out += fmt::format(
      "  cycle model ({}): {} cycles = {:.2f} us at {} GHz; {:.3f} fragments/clock, {:.2f} samples/clock\n", s.hw.name,
      s.total_cycles, s.frame_time_us, s.hw.clock.frequency_ghz, s.fragments_per_clock, s.samples_per_clock);
  out += fmt::format("  DRAM: {} B read, {} B written, {:.1f} of {:.1f} GB/s; busiest channel {:.0f}% busy\n",
                     s.dram.total_bytes_read(), s.dram.total_bytes_written(), s.dram_achieved_gbps, s.dram_peak_gbps,
                     100 * s.dram_utilization);
  if (s.compression_on) out += compression_summary(s.compression);
  for (const auto& p : s.passes)
    out += fmt::format("  pass {}: {} cycles; DRAM {} B read, {} B written\n", p.name, p.total_cycles,
                       p.dram.total_bytes_read(), p.dram.total_bytes_written());
  out += "  " + format_bottleneck(s) + "\n";
  out += "  bounds (cycles): " + format_bounds(s.bottleneck) + "\n";
  out += fmt::format("  host: {:.3f} s simulated, {:.2f} M fragments/s\n", run.sim_seconds,
                     run.sim_seconds > 0 ? run.counters.fragments / run.sim_seconds / 1e6 : 0.0);
  return out;
}

// ------------------------------------------------------------ --stats-interval

namespace {
bool has_blend(const CycleRun& run) {
  return run.stats.lists(int(Buffer::kTransmittance)) || run.stats.lists(int(Buffer::kAccum));
}
}  // namespace

std::vector<IntervalColumn> interval_columns(const CycleRun& run) {
  std::vector<IntervalColumn> c = {
      {"cycle_begin", "cycles", "first cycle of the interval (the run's cycles: a pass follows the previous)"},
      {"cycle_end", "cycles", "the cycle after the interval's last (the run's end for the last interval)"},
      {"fragments_retired", "fragments", "fragments that left the pipeline (written or killed) in the interval"},
      {"samples_written", "samples",
       "the write stage's samples_written, charged to the retirements that followed the writes"}};
  if (has_blend(run))
    c.push_back({"samples_blended", "samples", "blend passes: the blend stage's samples_blended, likewise"});
  for (int b = 0; b < kBuffers; ++b)
    if (run.stats.lists(b))
      c.push_back({std::string("dram_bytes_read.") + to_string(Buffer(b)), "bytes",
                   std::string("DRAM bytes read for the ") + to_string(Buffer(b)) + " buffer, by request cycle"});
  for (int b = 0; b < kBuffers; ++b)
    if (run.stats.lists(b))
      c.push_back({std::string("dram_bytes_written.") + to_string(Buffer(b)), "bytes",
                   std::string("DRAM bytes written for the ") + to_string(Buffer(b)) + " buffer, by request cycle"});
  c.push_back({"cache_hits", "accesses", "ROP cache read and write hits, every ROP"});
  c.push_back({"cache_misses", "accesses", "ROP cache read and write misses, every ROP"});
  c.push_back({"cache_hit_rate", "fraction", "cache_hits / (cache_hits + cache_misses); empty with no access"});
  if (run.intervals)
    for (const std::string& k : run.intervals->kinds())
      for (int a = 0; a < kActivities; ++a)
        c.push_back({k + "." + to_string(Activity(a)), "cycles",
                     "cycles the " + k + " units (summed over the ROPs) spent " + to_string(Activity(a))});
  return c;
}

std::string interval_csv(const CycleRun& run) {
  invariant(run.intervals != nullptr, "interval_csv is given a run with --stats-interval");
  const IntervalLog& log = *run.intervals;
  const bool blend = has_blend(run);
  std::string out;
  const auto cols = interval_columns(run);
  for (size_t i = 0; i < cols.size(); ++i) out += (i ? "," : "") + cols[i].name;
  out += "\n";
  const uint64_t total = run.stats.total_cycles;
  for (size_t i = 0; i < log.rows(); ++i) {
    const IntervalRow& r = log.at(i);
    const uint64_t begin = uint64_t(i) * log.period(), end = std::min(total, begin + log.period());
    out += fmt::format("{},{},{},{}", begin, std::max(end, begin), r.fragments_retired, r.samples_written);
    if (blend) out += fmt::format(",{}", r.samples_blended);
    for (int b = 0; b < kBuffers; ++b)
      if (run.stats.lists(b)) out += fmt::format(",{}", r.dram_bytes_read[size_t(b)]);
    for (int b = 0; b < kBuffers; ++b)
      if (run.stats.lists(b)) out += fmt::format(",{}", r.dram_bytes_written[size_t(b)]);
    const uint64_t lookups = r.cache_hits + r.cache_misses;
    out += fmt::format(",{},{},", r.cache_hits, r.cache_misses);
    if (lookups) out += fmt::format("{:.6f}", double(r.cache_hits) / double(lookups));
    for (size_t k = 0; k < log.kinds().size(); ++k)
      for (uint64_t c : log.activity(int(k), i)) out += fmt::format(",{}", c);
    out += "\n";
  }
  return out;
}

}  // namespace ropsim
