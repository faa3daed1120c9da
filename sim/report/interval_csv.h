// The --stats-interval CSV of a cycle run: its columns, declared with unit
// and meaning, and its rows.
#pragma once
#include <string>
#include <vector>

#include "sim/fidelity/cycle/cycle_run.h"

namespace ropsim {

/// One column of the --stats-interval CSV: its name, unit and meaning.
struct IntervalColumn {
  std::string name, unit, meaning;
};
/// The CSV's columns for this run (its method's buffers, its unit kinds), in
/// order; docs/reports.md "Statistics per interval" describes their patterns.
std::vector<IntervalColumn> interval_columns(const CycleRun& run);
/// The --stats-interval CSV: a header row of interval_columns(), then one
/// row per interval of run.intervals (which must be set).
std::string interval_csv(const CycleRun& run);

}  // namespace ropsim
