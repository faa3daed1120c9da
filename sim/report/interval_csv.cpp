#include "sim/report/interval_csv.h"

#include <fmt/format.h>

namespace ropsim {

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
