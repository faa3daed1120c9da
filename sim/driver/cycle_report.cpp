#include "cycle_report.h"

#include <fmt/format.h>

#include <map>

#include "image_io.h"

namespace ropsim {

namespace {

FunctionalRun as_functional(const CycleRun& run, const std::optional<Image>& reference) {
  FunctionalRun f;
  f.header = run.header;
  f.counters = run.counters;
  f.image = run.image;
  f.state_bytes = run.state_bytes;
  f.wall_seconds = run.wall_seconds;
  f.reference = reference;
  return f;
}

nlohmann::ordered_json activity_json(const UnitStats& u) {
  nlohmann::ordered_json j;
  for (int a = 0; a < kActivities; ++a) j[to_string(Activity(a))] = u.cycles[size_t(a)];
  return j;
}

}  // namespace

nlohmann::ordered_json cycle_stats_to_json(const CycleStats& s) {
  nlohmann::ordered_json t;
  t["clock_ghz"] = s.hw.clock.frequency_ghz;
  t["clock_period_ps"] = s.period_ps;
  t["total_cycles"] = s.total_cycles;
  t["pipeline_cycles"] = s.pipeline_cycles;
  t["frame_time_us"] = s.frame_time_us;
  t["fragments_per_clock"] = s.fragments_per_clock;
  t["samples_per_clock"] = s.samples_per_clock;
  t["bottleneck"] = s.bottleneck;
  t["memory_bound"] = s.memory_bound;
  nlohmann::ordered_json units = nlohmann::ordered_json::array();
  for (const auto& u : s.units) {
    nlohmann::ordered_json j;
    j["name"] = u.name;
    j["kind"] = u.kind;
    j["rop"] = u.rop;
    j["fragments"] = u.stats.fragments;
    j["samples"] = u.stats.samples;
    j["cycles"] = activity_json(u.stats);
    const uint64_t busy = u.stats.cycles[size_t(Activity::kBusy)];
    j["busy_fraction"] = s.total_cycles ? double(busy) / double(s.total_cycles) : 0.0;
    j["activations"] = u.stats.activations;
    for (const auto& e : u.extras) j[e.name] = e.value;
    units.push_back(j);
  }
  t["units"] = units;
  nlohmann::ordered_json fifos = nlohmann::ordered_json::array();
  for (const auto& f : s.fifos)
    fifos.push_back({{"name", f.name},
                     {"capacity_entries", f.capacity},
                     {"pushes", f.pushes},
                     {"mean_occupancy_entries", f.mean_occupancy},
                     {"max_occupancy_entries", f.max_occupancy},
                     {"full_cycles", f.full_cycles}});
  t["fifos"] = fifos;
  // Caches: the sum over ROPs, per buffer.
  nlohmann::ordered_json cache;
  CacheStats sum;
  for (const auto& c : s.caches)
    for (int b = 0; b < kBuffers; ++b) {
      sum.read_hits[size_t(b)] += c.read_hits[size_t(b)];
      sum.read_misses[size_t(b)] += c.read_misses[size_t(b)];
      sum.write_hits[size_t(b)] += c.write_hits[size_t(b)];
      sum.write_misses[size_t(b)] += c.write_misses[size_t(b)];
    }
  for (const auto& c : s.caches) {
    sum.merged += c.merged;
    sum.evictions += c.evictions;
    sum.dirty_evictions += c.dirty_evictions;
    sum.clear_fills += c.clear_fills;
  }
  for (int b = 0; b < kBuffers; ++b)
    cache[to_string(Buffer(b))] = {{"read_hits", sum.read_hits[size_t(b)]},
                                   {"read_misses", sum.read_misses[size_t(b)]},
                                   {"write_hits", sum.write_hits[size_t(b)]},
                                   {"write_misses", sum.write_misses[size_t(b)]}};
  uint64_t hits = 0, misses = 0;
  for (int b = 0; b < kBuffers; ++b) {
    hits += sum.read_hits[size_t(b)] + sum.write_hits[size_t(b)];
    misses += sum.read_misses[size_t(b)] + sum.write_misses[size_t(b)];
  }
  cache["hits"] = hits;
  cache["misses"] = misses;
  cache["hit_rate"] = hits + misses ? double(hits) / double(hits + misses) : 0.0;
  cache["merged_reads"] = sum.merged;
  cache["evictions"] = sum.evictions;
  cache["dirty_evictions"] = sum.dirty_evictions;
  cache["fast_clear_fills"] = sum.clear_fills;
  t["cache"] = cache;
  nlohmann::ordered_json dram;
  uint64_t rd = 0, wr = 0;
  for (int b = 0; b < kBuffers; ++b) {
    dram[to_string(Buffer(b))] = {{"bytes_read", s.dram.bytes_read[size_t(b)]},
                                  {"bytes_written", s.dram.bytes_written[size_t(b)]}};
    rd += s.dram.bytes_read[size_t(b)];
    wr += s.dram.bytes_written[size_t(b)];
  }
  dram["bytes_read"] = rd;
  dram["bytes_written"] = wr;
  dram["reads"] = s.dram.reads;
  dram["writes"] = s.dram.writes;
  dram["row_hits"] = s.dram.row_hits;
  dram["row_misses"] = s.dram.row_misses;
  dram["peak_gbps"] = s.dram_peak_gbps;
  dram["achieved_gbps"] = s.dram_achieved_gbps;
  dram["busiest_channel_utilization"] = s.dram_utilization;
  t["dram"] = dram;
  t["host"] = {{"systemc_activations", s.activations},
               {"unit_runs", s.unit_runs},
               {"decoupled", s.decoupled},
               {"fragment_tokens", s.tokens_allocated}};
  return t;
}

nlohmann::ordered_json cycle_report(const ReportContext& ctx, const CycleRun& run, const std::optional<Image>& reference) {
  nlohmann::ordered_json j = functional_report(ctx, as_functional(run, reference));
  j["fidelity"] = "cycle";
  j["hardware"] = {{"config", run.stats.hw.name}};
  j["hardware"]["resolved_toml"] = hw_config_to_toml(run.stats.hw);
  j["timing"] = cycle_stats_to_json(run.stats);
  j["host"]["sim_seconds"] = run.sim_seconds;
  j["host"]["simulated_fragments_per_second"] =
      run.sim_seconds > 0 ? double(run.counters.fragments) / run.sim_seconds : 0.0;
  return j;
}

std::string cycle_summary(const ReportContext& ctx, const CycleRun& run, const std::optional<Image>& reference) {
  const CycleStats& s = run.stats;
  std::string out = functional_summary(ctx, as_functional(run, reference));
  out += fmt::format("  cycle model ({}): {} cycles = {:.2f} us at {} GHz; {:.3f} fragments/clock, {:.2f} samples/clock\n",
                     s.hw.name, s.total_cycles, s.frame_time_us, s.hw.clock.frequency_ghz, s.fragments_per_clock,
                     s.samples_per_clock);
  uint64_t rd = 0, wr = 0;
  for (int b = 0; b < kBuffers; ++b) {
    rd += s.dram.bytes_read[size_t(b)];
    wr += s.dram.bytes_written[size_t(b)];
  }
  out += fmt::format("  DRAM: {} B read, {} B written, {:.1f} of {:.1f} GB/s; busiest channel {:.0f}% busy\n", rd, wr,
                     s.dram_achieved_gbps, s.dram_peak_gbps, 100 * s.dram_utilization);
  out += "  " + s.bottleneck + "\n";
  out += fmt::format("  host: {:.3f} s simulated, {:.2f} M fragments/s\n", run.sim_seconds,
                     run.sim_seconds > 0 ? run.counters.fragments / run.sim_seconds / 1e6 : 0.0);
  return out;
}

}  // namespace ropsim
