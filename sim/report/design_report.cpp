#include "sim/report/design_report.h"

namespace ropsim {

RtlDesign rtl_design_of(const HwConfig& hw) {
  RtlDesign d;
  d.name = hw.name;
  d.rop_units = int(hw.distributor.rop_units);
  d.alpha_ref_lanes = int(hw.alpha_ref.lanes);
  d.alpha_ref_stages = int(hw.alpha_ref.pipeline_depth);
  d.depth_lanes = int(hw.depth_test.samples_per_clock);
  d.depth_stages = int(hw.depth_test.latency_cycles);
  d.tracker_stages = int(hw.tracker.latency_cycles);
  d.opacity_lanes = int(hw.writeback.samples_per_clock);
  d.sorter_kind = to_string(hw.sorter.kind);
  d.numerics = hw.numerics;
  return d;
}

ReportContext with_design(const ReportContext& ctx, const HwConfig& hw) {
  ReportContext c = ctx;
  c.design = rtl_design_of(hw);
  return c;
}

void put_hw_resolved(Fields f, const HwConfig& hw, const std::string& prefix) {
  for_each_hw_value(hw, [&](const ParamInfo& p, const HwValue& v) {
    const auto dot = p.key.find('.');
    Fields sec = f.obj(p.key.substr(0, dot));
    const std::string key = p.key.substr(dot + 1), meaning = prefix + p.meaning;
    std::visit([&](const auto& x) { sec.put(key, x, p.unit, meaning); }, v);
  });
}

nlohmann::ordered_json hw_config_to_json(const HwConfig& hw) {
  nlohmann::ordered_json j;
  put_hw_resolved(Fields(j, nullptr), hw);
  return j;
}

void put_hardware(Fields hw, const HwConfig& c) {
  hw.put("config", c.name, "-", "cycle: the design file (or \"built-in defaults\"), \"with --hw-set\" when overridden");
  hw.put("resolved_toml", hw_config_to_toml(c), "-", "cycle: every hardware parameter as simulated, as TOML");
  hw.put("overrides", c.overrides, "-",
         "cycle: the --hw-set assignments applied over the design file, in order, as given");
  hw.put("digest", hw_digest_hex(c), "-",
         "cycle: 8 hex digits of FNV-1a 64 over the resolved design (in default output names: -hwDIGEST)");
  // Each parameter's unit and meaning come from the parameter table (hw_params()).
  put_hw_resolved(hw.obj("resolved"), c, "cycle: ");
}

}  // namespace ropsim
