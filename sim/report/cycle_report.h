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
#include "sim/report/report.h"

namespace ropsim {

/// The design as the silicon cost sees it (rtl_cost.h): the unit instances'
/// lanes and stages, the sorter, the ROPs and the numerics of `hw`.
RtlDesign rtl_design_of(const HwConfig& hw);
/// ctx with `design` set to hw's (the reports of the timed fidelities).
ReportContext with_design(const ReportContext& ctx, const HwConfig& hw);

/// The "timing" section: every timing figure with its unit and meaning.
void put_cycle_stats(Fields t, const CycleStats& s);
nlohmann::ordered_json cycle_stats_to_json(const CycleStats& s);
/// Every hardware parameter as an object section -> key -> typed value, each
/// declared with the unit and meaning of its row in hw_params() (prefixed).
void put_hw_resolved(Fields f, const HwConfig& hw, const std::string& prefix = "");
nlohmann::ordered_json hw_config_to_json(const HwConfig& hw);
/// The bottleneck as one line.
std::string format_bottleneck(const CycleStats& s);
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
/// Where a sampled run's live-points came from.
struct LibrarySource {
  std::string path;    ///< the library file read, or "" (recorded by this run)
  double seconds = 0;  ///< host time to record or read it
};
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
