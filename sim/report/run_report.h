// The one report printer and the one summary printer of a run, whatever its
// fidelity (sim/fidelity/run.h): the functional report every run writes,
// with the design, timing and host sections of a timed one (cycle_report.h
// writes those sections, docs/reports.md lists every field).
#pragma once
#include <nlohmann/json.hpp>
#include <string>

#include "sim/fidelity/run.h"
#include "sim/report/report.h"

namespace ropsim {

/// The JSON report of a run; with a sink, also each field's description.
nlohmann::ordered_json run_report(const ReportContext& ctx, const RunResult& run, FieldSink* sink = nullptr);

/// The human summary of a run (a few lines).
std::string run_summary(const ReportContext& ctx, const RunResult& run);

}  // namespace ropsim
