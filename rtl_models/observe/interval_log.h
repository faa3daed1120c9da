// Statistics per interval of a cycle run (--stats-interval N): what happened
// in cycles [k N, (k + 1) N) of the run, for every k, as one CSV row each.
// Every source records an event under the cycle it happens at -- a fragment
// at its retirement, a DRAM access and a cache lookup at their request
// cycle, a unit's activity over the cycles it spans -- so the rows are the
// same whether units run decoupled or in lockstep, and each column adds up
// to the run's total (CycleStats). Multi-pass methods: a pass's cycles
// follow the previous pass's (set_base). Its growth is charged to the
// memory budget (--memory-limit).
#pragma once
#include <algorithm>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "rtl_models/algo/buffers.h"
#include "util/memory_budget.h"

namespace ropsim {

/// The activities a unit's cycles are charged to (unit.h Activity).
constexpr int kIntervalActivities = 6;

struct IntervalRow {
  uint64_t fragments_retired = 0;  ///< fragments that left the pipeline
  uint64_t samples_written = 0;    ///< the write stage's samples_written, at the retirements that followed
  uint64_t samples_blended = 0;    ///< the blend stage's samples_blended, likewise
  std::array<uint64_t, kBuffers> dram_bytes_read{}, dram_bytes_written{};
  uint64_t cache_hits = 0, cache_misses = 0;  ///< ROP cache lookups (reads and writes), every ROP
};

class IntervalLog {
 public:
  /// period: N cycles per row, >= 1.
  explicit IntervalLog(uint64_t period) : period_(period ? period : 1) {}
  uint64_t period() const { return period_; }
  /// The current pass's first cycle in the run (its cycles count from 0).
  void set_base(uint64_t cycle) { base_ = cycle; }
  uint64_t base() const { return base_; }

  /// The row of the current pass's cycle.
  IntervalRow& row(uint64_t cycle) {
    const size_t i = size_t((base_ + cycle) / period_);
    if (i >= rows_.size()) grow(i + 1);
    return rows_[i];
  }
  /// The index of unit kind `kind` ("depth_test"), added on first use.
  int kind(const std::string& kind);
  /// Charges the current pass's cycles [from, to) of one unit of kind k to
  /// activity a, split at the interval boundaries.
  void add_activity(int k, int a, uint64_t from, uint64_t to);

  /// Rows up to the run's end (total cycles), the last one possibly partial.
  void finish(uint64_t total_cycles);
  size_t rows() const { return rows_.size(); }
  const IntervalRow& at(size_t i) const { return rows_[i]; }
  const std::vector<std::string>& kinds() const { return kinds_; }
  /// Cycles of kind k's units (summed over its instances) in row i, per activity.
  const std::array<uint64_t, kIntervalActivities>& activity(int k, size_t i) const { return activity_[size_t(k)][i]; }

 private:
  void grow(size_t n);
  uint64_t period_, base_ = 0;
  std::vector<IntervalRow> rows_;
  std::vector<std::string> kinds_;
  std::vector<std::vector<std::array<uint64_t, kIntervalActivities>>> activity_;  // [kind][row]
  BudgetShare mem_;
};

inline int IntervalLog::kind(const std::string& k) {
  for (size_t i = 0; i < kinds_.size(); ++i)
    if (kinds_[i] == k) return int(i);
  kinds_.push_back(k);
  mem_.add(rows_.capacity() * sizeof(activity_[0][0]) + sizeof(activity_[0]), "the --stats-interval rows");
  activity_.emplace_back(rows_.size());
  activity_.back().reserve(rows_.capacity());
  return int(kinds_.size() - 1);
}

inline void IntervalLog::grow(size_t n) {
  if (n <= rows_.size()) return;
  if (n > rows_.capacity()) {
    // Rows double, so a run pays for its rows' memory in a few steps.
    const size_t cap = std::max(n, rows_.capacity() * 2);
    const size_t bytes_per_row = sizeof(IntervalRow) + kinds_.size() * sizeof(activity_[0][0]);
    mem_.add((cap - rows_.capacity()) * bytes_per_row, "the --stats-interval rows");
    rows_.reserve(cap);
    for (auto& a : activity_) a.reserve(cap);
  }
  rows_.resize(n);
  for (auto& a : activity_) a.resize(n);
}

inline void IntervalLog::add_activity(int k, int a, uint64_t from, uint64_t to) {
  uint64_t t = base_ + from;
  const uint64_t end = base_ + to;
  while (t < end) {
    const size_t i = size_t(t / period_);
    if (i >= rows_.size()) grow(i + 1);
    const uint64_t stop = std::min(end, (uint64_t(i) + 1) * period_);
    activity_[size_t(k)][i][size_t(a)] += stop - t;
    t = stop;
  }
}

inline void IntervalLog::finish(uint64_t total_cycles) {
  if (total_cycles > 0) grow(size_t((total_cycles + period_ - 1) / period_));
}

}  // namespace ropsim
