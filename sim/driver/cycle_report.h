// Report printers for cycle runs: the JSON report (the functional report plus
// "hardware" and "timing" sections; docs/reports.md) and the human summary.
#pragma once
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "cycle_run.h"
#include "report.h"

namespace ropsim {

nlohmann::ordered_json cycle_stats_to_json(const CycleStats& s);
/// reference: the A-buffer image when --vs-reference was asked for.
nlohmann::ordered_json cycle_report(const ReportContext& ctx, const CycleRun& run, const std::optional<Image>& reference);
std::string cycle_summary(const ReportContext& ctx, const CycleRun& run, const std::optional<Image>& reference);

}  // namespace ropsim
