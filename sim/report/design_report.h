// The design in a report: the "hardware" section (every parameter with its
// unit and meaning), the design as JSON, and the design as the silicon cost
// sees it.
#pragma once
#include <nlohmann/json.hpp>
#include <string>

#include "rtl_models/config/hw_config.h"
#include "rtl_models/cost/rtl_cost.h"
#include "sim/report/report.h"
#include "sim/report/report_fields.h"

namespace ropsim {

/// The design as the silicon cost sees it (rtl_cost.h): the unit instances'
/// lanes and stages, the sorter, the ROPs and the numerics of `hw`.
RtlDesign rtl_design_of(const HwConfig& hw);
/// ctx with `design` set to hw's (the reports of the timed fidelities).
ReportContext with_design(const ReportContext& ctx, const HwConfig& hw);
/// Every hardware parameter as an object section -> key -> typed value, each
/// declared with the unit and meaning of its row in hw_params() (prefixed).
void put_hw_resolved(Fields f, const HwConfig& hw, const std::string& prefix = "");
nlohmann::ordered_json hw_config_to_json(const HwConfig& hw);
/// The report's "hardware" section: the design's name, file and every
/// parameter (put_hw_resolved).
void put_hardware(Fields hw, const HwConfig& c);

}  // namespace ropsim
