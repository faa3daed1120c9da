// Report printers for cycle runs: the JSON report (the functional report plus
// "hardware" and "timing" sections; docs/reports.md) and the human summary.
#pragma once
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "sim/fidelity/approximate/approximate.h"
#include "sim/fidelity/cycle/cycle_run.h"
#include "sim/fidelity/sampled/livepoints.h"
#include "sim/report/design_report.h"
#include "sim/report/interval_csv.h"
#include "sim/report/report.h"
#include "sim/report/timing_sections.h"

namespace ropsim {

/// reference: the A-buffer image when --vs-reference was asked for; with a
/// sink, also each field's description.
nlohmann::ordered_json cycle_report(const ReportContext& ctx, const CycleRun& run,
                                    const std::optional<Image>& reference, FieldSink* sink = nullptr);
/// Every report field, functional and cycle, with its unit and meaning, in
/// report order (docs/reports.md).
std::vector<FieldDoc> report_field_docs();
std::string cycle_summary(const ReportContext& ctx, const CycleRun& run, const std::optional<Image>& reference);

/// The report of a sampled run (--fidelity sampled): the golden model's
/// counters and image, the design, and the estimates under the cycle report's
/// keys, each with its 95 % interval (timing.total_cycles_ci95, ...).
nlohmann::ordered_json sampled_report(const ReportContext& ctx, const LivePoints& lib, const SampledRun& s,
                                      const HwConfig& hw, double wall_seconds, const LibrarySource& from,
                                      const std::optional<Image>& reference = std::nullopt, FieldSink* sink = nullptr);
std::string sampled_summary(const ReportContext& ctx, const LivePoints& lib, const SampledRun& s, const HwConfig& hw,
                            double wall_seconds, const LibrarySource& from,
                            const std::optional<Image>& reference = std::nullopt);

/// The report of an approximate run (--fidelity approximate): the golden
/// model's counters and image, the design, and the analytical model's
/// estimates under the cycle report's keys, with the bounds it computed
/// (timing.approximate.*).
nlohmann::ordered_json approximate_report(const ReportContext& ctx, const ApproxRun& run,
                                          const std::optional<Image>& reference = std::nullopt,
                                          FieldSink* sink = nullptr);
std::string approximate_summary(const ReportContext& ctx, const ApproxRun& run,
                                const std::optional<Image>& reference = std::nullopt);

}  // namespace ropsim
