#include "sim/report/timing_sections.h"

#include <fmt/format.h>

namespace ropsim {

namespace {

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
void put_unit_identity(Fields j, const UnitReport& u) {
  j.put("name", u.name, "-", "the unit instance (SystemC name)");
  j.put("kind", u.kind, "-",
        "trace_source, distributor, pixel_ordering, depth_test, coverage_tracker, sample_sorter, "
        "alpha_ref_gen, writeback or blend");
  j.put("rop", u.rop, "-", "the ROP unit it belongs to (-1: shared)");
}

/// A unit instance's cycles per activity (cycle and sampled reports).
void put_unit_activity(Fields j, const UnitReport& u, uint64_t total_cycles) {
  Fields c = j.obj("cycles");
  for (int a = 0; a < kActivities; ++a)
    c.put(to_string(Activity(a)), u.stats.cycles[size_t(a)], "cycles",
          std::string(activity_meaning(Activity(a))) + " (the activities sum to total_cycles)");
  const uint64_t busy = u.stats.cycles[size_t(Activity::kBusy)];
  j.put("busy_fraction", total_cycles ? double(busy) / double(total_cycles) : 0.0, "fraction",
        "busy cycles / total_cycles");
}

/// The ROP caches' figures, summed over the ROPs (cycle and approximate reports).
void put_cache_stats(Fields cache, const CacheStats& sum, uint32_t listed) {
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
void put_dram_traffic(Fields dram, const DramStats& d, uint32_t listed) {
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
/// approximate model's tag_compression.h counts the same): per
/// compressed surface, its line transfers' bytes before and after
/// compression, the block sizes of the tiles written, and its state bits'
/// traffic (included in the DRAM bytes of the surface).
void put_compression_traffic(Fields c, const CompressionTraffic& s, const HwConfig& hw) {
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
std::string compression_summary(const CompressionTraffic& c) {
  uint64_t before = 0, after = 0;
  for (size_t b = 0; b < size_t(kBuffers); ++b) {
    before += c.bytes_written_uncompressed[b] + c.bytes_read_uncompressed[b];
    after += c.bytes_written[b] + c.bytes_read[b];
  }
  return fmt::format(
      "  compression: {} B of compressed-surface traffic moved as {} B; Hi-Z rejected {} of {} fragments\n", before,
      after, c.hiz_rejected, c.hiz_tests);
}

std::string format_bottleneck(const CycleStats& s) { return format_bottleneck(s.bottleneck); }

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

nlohmann::ordered_json cycle_stats_to_json(const CycleStats& s) {
  nlohmann::ordered_json t;
  put_cycle_stats(Fields(t, nullptr), s);
  return t;
}

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

}  // namespace ropsim
