// The silicon cost of a design (rtl_models/cost, docs/rtl.md "Cost of a
// design"): the committed synthesis sweep is what the binary holds; a sweep
// point's cost is its row; the models stay within their documented bounds on
// rows they were not fitted to; what has no reference RTL or lies outside the
// models is null with a reason; and a study's points carry the cost.
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "rtl_models/cost/rtl_cost.h"
#include "tests/study_test_util.h"

using namespace ropsim;
using namespace ropsim_test;

namespace {

const std::string kCsv = std::string(ROPSIM_SOURCE_DIR) + "/docs/data/rtl_synth_sweep.csv";

/// The built-in design's units (HwConfig's defaults, which
/// ConfigSilicon... checks through `ropsim config --silicon`), 16 spp, 1024 x 1024.
RtlDesign default_design() {
  RtlDesign d;
  d.name = "test";
  d.rop_units = 4;
  d.spp = 16;
  d.width = d.height = 1024;
  d.alpha_ref_lanes = 16;
  d.alpha_ref_stages = 4;
  d.depth_lanes = 16;
  d.depth_stages = 2;
  d.tracker_stages = 1;
  d.opacity_lanes = 16;
  d.sorter_kind = "bitonic";
  return d;
}

}  // namespace

// The table built into ropsim is the committed CSV, row for row, and every
// row looked up by its own parameters gives its own figures.
TEST(SiliconCost, TheBuiltInTableIsTheCommittedSweepAndASweepPointIsItsRow) {
  const auto file = parse_rtl_synth_csv(slurp(kCsv), kCsv);
  const auto& built = rtl_synth_table();
  ASSERT_EQ(file.size(), built.size()) << "rebuild: the CSV changed after the build (the build embeds it again)";
  for (size_t i = 0; i < file.size(); ++i) {
    const RtlSynthRow& r = file[i];
    EXPECT_EQ(r.module, built[i].module);
    EXPECT_EQ(r.params, built[i].params) << r.module << " " << r.params_text;
    EXPECT_EQ(r.nand2_eq, built[i].nand2_eq) << r.module << " " << r.params_text;
    // nand2_eq is transistors / 4 (synth.sh), the declared relation.
    EXPECT_EQ(r.nand2_eq, r.transistors / 4) << r.module << " " << r.params_text;
    const RtlCost c = rtl_cost(r.module, r.params);
    EXPECT_EQ(c.source, CostSource::kSweep) << r.module << " " << r.params_text << ": " << c.reason;
    ASSERT_TRUE(c.nand2_eq && c.flipflops && c.levels) << r.module << " " << r.params_text;
    EXPECT_EQ(*c.nand2_eq, double(r.nand2_eq)) << r.module << " " << r.params_text;
    EXPECT_EQ(*c.flipflops, r.flipflops) << r.module << " " << r.params_text;
    EXPECT_EQ(*c.levels, double(r.levels)) << r.module << " " << r.params_text;
  }
  // A malformed table is refused, naming the line.
  EXPECT_THROW(parse_rtl_synth_csv("module,params,cells,flipflops,transistors,nand2_eq,levels,seconds\n"
                                   "rop_depth_compare,\"LANES=4 STAGES=2\",895,10,x,815,21,\n",
                                   "t.csv"),
               std::runtime_error);
}

// The models' flip-flop counts are structural (the RTL's registers): equal
// to synthesis on every row of the sweep, not fitted.
TEST(SiliconCost, FlipFlopCountsAreExactOnEveryRow) {
  int checked = 0;
  for (const RtlSynthRow& r : rtl_synth_table()) {
    const RtlCost m = rtl_cost_model(r.module, r.params, rtl_synth_table());
    if (m.reason.find("outside the modelled") != std::string::npos) continue;  // the sorter's N = 1, 2: rows only
    ASSERT_EQ(m.source, CostSource::kModel) << r.module << " " << r.params_text << ": " << m.reason;
    if (!m.flipflops) continue;  // the sorter: Yosys trims its key registers, no exact count
    EXPECT_EQ(*m.flipflops, r.flipflops) << r.module << " " << r.params_text;
    ++checked;
  }
  EXPECT_GT(checked, 60);
}

// Leave-one-out: each row held out, the module's model refitted to the
// others predicts it within the documented bound (rtl_model_bounds, the
// figures of docs/rtl.md). A row whose held-out fit is underdetermined (the
// only row of its kind) must say so rather than give a number.
TEST(SiliconCost, ModelsPredictHeldOutSweepRowsWithinTheirBounds) {
  int checked = 0;
  for (const HeldOutError& e : rtl_model_check(rtl_synth_table())) {
    const RtlModelBounds b = rtl_model_bounds(e.module);
    if (!e.nand2_error) {  // outside the model's range (the sorter's N = 1, 2): no number
      EXPECT_NE(e.reason.find("outside the modelled"), std::string::npos) << e.module << " " << e.params;
      continue;
    }
    ++checked;
    EXPECT_LE(std::fabs(*e.nand2_error), b.nand2)
        << e.module << " " << e.params << ": NAND2 eq. off by " << 100 * *e.nand2_error << " %";
    if (e.levels_error)
      EXPECT_LE(std::fabs(*e.levels_error), b.levels)
          << e.module << " " << e.params << ": levels off by " << 100 * *e.levels_error << " %";
    else
      EXPECT_NE(e.reason.find("levels"), std::string::npos) << e.module << " " << e.params;
  }
  EXPECT_GT(checked, 70);
}

// Outside the models, or without reference RTL: null with the reason.
TEST(SiliconCost, UnsupportedParametersAndUnitsAreNullWithAReason) {
  const RtlCost unknown = rtl_cost("rop_blend", {{"LANES", 4}});
  EXPECT_EQ(unknown.source, CostSource::kNone);
  EXPECT_FALSE(unknown.nand2_eq);
  EXPECT_NE(unknown.reason.find("no reference RTL"), std::string::npos) << unknown.reason;
  const RtlCost wide =
      rtl_cost("rop_alpha_ref",
               {{"LANES", 16}, {"STAGES", 4}, {"HASH_BITS", 40}, {"SPP", 16}, {"SID_BITS", 32}, {"PIXEL_BITS", 32}});
  EXPECT_FALSE(wide.nand2_eq);
  EXPECT_NE(wide.reason.find("HASH_BITS=40 outside"), std::string::npos) << wide.reason;
  const RtlCost odd = rtl_cost("rop_bitonic_sorter", {{"N", 12}});
  EXPECT_FALSE(odd.nand2_eq);
  EXPECT_NE(odd.reason.find("power of two"), std::string::npos) << odd.reason;

  RtlDesign rank = default_design();
  rank.sorter_kind = "rank";
  const DesignCost c = design_cost(rank);
  EXPECT_FALSE(c.rop_nand2_eq);
  EXPECT_FALSE(c.total_nand2_eq);
  EXPECT_NE(c.reason.find("sorter.kind rank"), std::string::npos) << c.reason;
  for (const UnitCost& u : c.units)
    EXPECT_EQ(bool(u.cost.nand2_eq), u.unit != "sorter") << u.unit << ": only the sorter is unknown";

  RtlDesign enderton = default_design();
  enderton.method = "enderton";
  enderton.lk_selection = false;
  const DesignCost e = design_cost(enderton);
  EXPECT_FALSE(e.total_nand2_eq);
  EXPECT_TRUE(e.units.empty());
  EXPECT_NE(e.reason.find("only lk's units"), std::string::npos) << e.reason;

  RtlDesign blend = default_design();
  blend.blend_pass = true;
  const DesignCost bl = design_cost(blend);
  EXPECT_FALSE(bl.total_nand2_eq);
  EXPECT_NE(bl.reason.find("blend unit"), std::string::npos) << bl.reason;
}

// The built-in design is a sweep point unit by unit, its sums add up, and
// the cost grows with the hash width and the lanes.
TEST(SiliconCost, TheDefaultDesignIsSweepRowsAndTheCostGrowsWithBitsAndLanes) {
  const DesignCost d = design_cost(default_design());
  ASSERT_TRUE(d.total_nand2_eq) << d.reason;
  double sum = 0;
  for (const UnitCost& u : d.units) {
    EXPECT_EQ(u.cost.source, u.unit == "hilbert_index" ? CostSource::kModel : CostSource::kSweep)
        << u.unit << " " << u.params << " (ORDER=10 is not in the sweep)";
    sum += *u.cost.nand2_eq;
    if (u.unit == "alpha_ref") {
      EXPECT_EQ(*u.cost.nand2_eq, 252754.0) << "the CSV's 16-lane 32-bit generator";
    }
  }
  EXPECT_DOUBLE_EQ(*d.rop_nand2_eq, sum);
  EXPECT_DOUBLE_EQ(*d.total_nand2_eq, 4 * sum);

  auto alpha = [](const DesignCost& c) {
    for (const UnitCost& u : c.units)
      if (u.unit == "alpha_ref") return *u.cost.nand2_eq;
    return -1.0;
  };
  double prev = 0, prev_total = 0;
  for (int h = 8; h <= 32; ++h) {
    RtlDesign x = default_design();
    x.numerics.hash_bits = h;
    const DesignCost c = design_cost(x);
    ASSERT_TRUE(c.total_nand2_eq) << "hash_bits " << h << ": " << c.reason;
    EXPECT_GT(alpha(c), prev) << "hash_bits " << h;
    EXPECT_GT(*c.total_nand2_eq, prev_total) << "hash_bits " << h;
    prev = alpha(c);
    prev_total = *c.total_nand2_eq;
  }
  prev = 0;
  for (int lanes : {1, 2, 3, 4, 8, 12, 16, 32, 64}) {
    RtlDesign x = default_design();
    x.alpha_ref_lanes = lanes;
    const DesignCost c = design_cost(x);
    ASSERT_TRUE(c.total_nand2_eq) << "lanes " << lanes << ": " << c.reason;
    EXPECT_GT(alpha(c), prev) << "lanes " << lanes;
    prev = alpha(c);
  }
}

// A study's points carry the cost beside their other results: the
// alpha-reference generator of each point is its sweep row, and the total
// grows with hash_bits and with alpha_ref.lanes. A method without reference
// RTL reports null with the reason.
TEST(SiliconCost, StudyPointsCarryTheCostAndItGrowsWithHashBitsAndLanes) {
  Scratch s;
  s.put("cost.toml", R"(
[study]
reference = false
[inputs]
scenes = ["eight-layers"]
[axes]
fidelity = "approximate"
spp = 4
width = 16
height = 16
hash_bits = [8, 16, 32]
"alpha_ref.lanes" = [4, 16]
)");
  const Ran r = ropsim_test::ropsim(s.dir, "study run cost.toml --out st -j 2 --quiet");
  ASSERT_EQ(r.status, 0) << r.err;
  const Rows rows = export_rows(s.dir, "st");
  ASSERT_EQ(rows.size(), 6u);
  const std::map<std::pair<int, int>, double> csv = {{{8, 4}, 2643},    {{8, 16}, 10192}, {{16, 4}, 14344},
                                                     {{16, 16}, 56504}, {{32, 4}, 63573}, {{32, 16}, 252754}};
  std::map<std::pair<int, int>, double> total;
  for (const auto& row : rows) {
    const int h = std::stoi(row.at("hash_bits")), l = std::stoi(row.at("alpha_ref.lanes"));
    EXPECT_EQ(row.at("silicon.units.alpha_ref.estimate"), "sweep");
    EXPECT_EQ(std::stod(row.at("silicon.units.alpha_ref.nand2_eq")), csv.at({h, l})) << h << " bits, " << l;
    ASSERT_FALSE(row.at("silicon.total.nand2_eq").empty()) << row.at("silicon.reason");
    total[{h, l}] = std::stod(row.at("silicon.total.nand2_eq"));
  }
  auto at = [&](int h, int l) { return total[std::make_pair(h, l)]; };
  for (int l : {4, 16}) {
    EXPECT_LT(at(8, l), at(16, l)) << l << " lanes";
    EXPECT_LT(at(16, l), at(32, l)) << l << " lanes";
  }
  for (int h : {8, 16, 32}) EXPECT_LT(at(h, 4), at(h, 16)) << h << " bits";

  const Ran e = ropsim_test::ropsim(
      s.dir, "run --scene eight-layers --spp 4 --width 16 --height 16 --method enderton --report -");
  ASSERT_EQ(e.status, 0) << e.err;
  const auto j = nlohmann::json::parse(e.out);
  EXPECT_TRUE(j["silicon"]["total"]["nand2_eq"].is_null());
  EXPECT_NE(j["silicon"]["reason"].get<std::string>().find("only lk's units"), std::string::npos);
}

// `ropsim config --silicon` costs a design file with its overrides (the
// built-in design: its units are these sweep rows, the sums those of
// design_cost), refuses a bad spp in one line, and --silicon-check lists
// every module's held-out errors within their bounds.
TEST(SiliconCost, ConfigSiliconCostsTheBuiltInDesignAndChecksTheModels) {
  Scratch s;
  const Ran r = ropsim_test::ropsim(s.dir, "config --silicon");
  ASSERT_EQ(r.status, 0) << r.err;
  const DesignCost d = design_cost(default_design());
  ASSERT_TRUE(d.total_nand2_eq);
  EXPECT_NE(r.out.find(" 252754 "), std::string::npos) << "the 16-lane 32-bit generator's row:\n" << r.out;
  EXPECT_NE(r.out.find(" " + std::to_string(int64_t(*d.total_nand2_eq)) + " "), std::string::npos)
      << "the built-in design's total must be design_cost's of HwConfig's defaults:\n"
      << r.out;
  const Ran rank = ropsim_test::ropsim(s.dir, "config --silicon --hw-set sorter.kind=rank --spp 8");
  ASSERT_EQ(rank.status, 0) << rank.err;
  EXPECT_NE(rank.out.find("# no sums: sorter: sorter.kind rank"), std::string::npos) << rank.out;
  const Ran bad = ropsim_test::ropsim(s.dir, "config --silicon --spp 3");
  EXPECT_EQ(bad.status, 1);
  EXPECT_NE(bad.err.find("--spp 3"), std::string::npos) << bad.err;
  const Ran check = ropsim_test::ropsim(s.dir, "config --silicon-check");
  ASSERT_EQ(check.status, 0) << check.err;
  for (const std::string& m : rtl_cost_modules()) EXPECT_NE(check.out.find("| " + m + " |"), std::string::npos) << m;
}
