// `ropsim config [FILE] [--hw-set K=V]... [--json]`: print the hardware design
// resolved (as TOML, or --json as section -> key -> value) with its memory
// estimate (memory_estimate.h), or --markdown the parameter table
// (docs/config.md); --silicon the design's silicon cost and --silicon-check
// its models' held-out errors (docs/rtl.md).
#include <fmt/format.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <memory>

#include "rtl_models/config/hw_config.h"
#include "rtl_models/cost/rtl_cost.h"
#include "rtl_models/top/memory_estimate.h"
#include "sim/cli/cli_common.h"
#include "sim/report/cycle_report.h"
#include "util/errors.h"
#include "util/memory_budget.h"

namespace ropsim {

namespace {

struct ConfigOpts {
  std::string file;
  std::vector<std::string> hw_sets;
  bool markdown = false, json = false;
  bool silicon = false, silicon_check = false;
  int spp = 16, width = 1024, height = 1024;
};

std::string figure(const std::optional<double>& v) { return v ? fmt::format("{:.0f}", *v) : "null"; }

/// --silicon: the design's LK units, each a sweep row or a model estimate.
int print_silicon(const HwConfig& c, const ConfigOpts& o) {
  if (!is_valid_spp(o.spp)) throw UserError("--spp " + std::to_string(o.spp) + ": expected 1, 2, 4, ..., 64");
  RtlDesign d = rtl_design_of(c);
  d.spp = o.spp;
  d.width = o.width;
  d.height = o.height;
  const DesignCost cost = design_cost(d);
  fmt::print("# silicon cost of {} (lk, {} spp, {}x{}; docs/rtl.md \"Cost of a design\")\n", c.name, o.spp, o.width,
             o.height);
  fmt::print("{:<15} {:<62} {:>10} {:>10} {:>7}  {}\n", "unit", "parameters", "NAND2 eq.", "flip-flops", "levels",
             "estimate");
  for (const UnitCost& u : cost.units) {
    std::string est = to_string(u.cost.source);
    if (u.cost.source == CostSource::kModel) est += fmt::format(" (+-{:.0f} %)", 100 * u.cost.nand2_error_bound);
    if (!u.cost.reason.empty()) est += ": " + u.cost.reason;
    fmt::print("{:<15} {:<62} {:>10} {:>10} {:>7}  {}\n", u.unit, u.params, figure(u.cost.nand2_eq),
               u.cost.flipflops ? std::to_string(*u.cost.flipflops) : "null", figure(u.cost.levels), est);
  }
  fmt::print("{:<15} {:<62} {:>10} {:>10} {:>7}\n", "one ROP", "", figure(cost.rop_nand2_eq),
             cost.rop_flipflops ? std::to_string(*cost.rop_flipflops) : "null", figure(cost.rop_levels));
  fmt::print("{:<15} {:<62} {:>10} {:>10}\n", fmt::format("{} ROPs", d.rop_units), "", figure(cost.total_nand2_eq),
             cost.total_flipflops ? std::to_string(*cost.total_flipflops) : "null");
  if (!cost.reason.empty()) fmt::print("# no sums: {}\n", cost.reason);
  return 0;
}

/// --silicon-check: each module's model against the sweep rows it was not fitted to.
int print_silicon_check() {
  struct Worst {
    int rows = 0, held = 0, levels = 0;
    double nand2 = 0, lv = 0;
  };
  std::map<std::string, Worst> w;
  for (const HeldOutError& e : rtl_model_check(rtl_synth_table())) {
    Worst& x = w[e.module];
    ++x.rows;
    if (e.nand2_error) {
      ++x.held;
      x.nand2 = std::max(x.nand2, std::fabs(*e.nand2_error));
    }
    if (e.levels_error) {
      ++x.levels;
      x.lv = std::max(x.lv, std::fabs(*e.levels_error));
    }
  }
  fmt::print("# leave-one-out: each sweep row predicted by its module's model fitted to the other rows\n");
  fmt::print(
      "| module | rows | predicted | largest NAND2 error | bound | levels predicted | largest levels error | bound "
      "|\n");
  fmt::print("|---|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const std::string& m : rtl_cost_modules()) {
    const Worst& x = w[m];
    const RtlModelBounds b = rtl_model_bounds(m);
    fmt::print("| {} | {} | {} | {:.1f} % | {:.0f} % | {} | {:.1f} % | {:.0f} % |\n", m, x.rows, x.held, 100 * x.nand2,
               100 * b.nand2, x.levels, 100 * x.lv, 100 * b.levels);
  }
  return 0;
}

/// The design's memory estimate for a run of o's screen (docs/config.md "Memory estimate").
MemoryShape shape_of(const ConfigOpts& o) {
  if (!is_valid_spp(o.spp)) throw UserError("--spp " + std::to_string(o.spp) + ": expected 1, 2, 4, ..., 64");
  MemoryShape s;
  s.width = uint32_t(o.width);
  s.height = uint32_t(o.height);
  s.spp = o.spp;
  return s;
}

nlohmann::ordered_json estimate_to_json(const MemoryEstimate& cycle, const MemoryEstimate& approx) {
  nlohmann::ordered_json j;
  j["unit"] = "bytes";
  j["model"] = to_string(cycle.model);
  j["assumes"] = {{"width", cycle.shape.width},
                  {"height", cycle.shape.height},
                  {"spp", cycle.shape.spp},
                  {"method", to_string(cycle.shape.method)}};
  j["rop_units"] = cycle.rops;
  j["total_bytes"] = cycle.total_bytes;
  j["per_rop_bytes"] = cycle.per_rop_bytes;
  j["shared_bytes"] = cycle.shared_bytes;
  nlohmann::ordered_json parts = nlohmann::ordered_json::object();
  for (const MemoryTerm& t : cycle.terms)
    parts[t.name] = {{"bytes", t.bytes},
                     {"per_rop_bytes", t.per_rop_bytes},
                     {"shared_bytes", t.shared_bytes},
                     {"keys", t.keys},
                     {"meaning", t.meaning}};
  j["parts"] = parts;
  j["approximate_total_bytes"] = approx.total_bytes;
  const MemoryBudget& b = memory_budget();
  j["memory_limit_bytes"] = b.limit();
  j["fits_memory_limit"] = b.limit() == 0 || cycle.total_bytes <= b.limit();
  return j;
}

/// The estimate as TOML comments (the output still loads as the design).
void print_estimate(const MemoryEstimate& e, const MemoryEstimate& approx) {
  fmt::print(
      "\n# memory estimate of the cycle model (a run of {}x{} at {} spp, {}; docs/config.md \"Memory estimate\"):\n",
      e.shape.width, e.shape.height, e.shape.spp, to_string(e.shape.method));
  fmt::print("#   {} = {} ROPs x {} + {} shared ({} bytes)\n", format_bytes(e.total_bytes), e.rops,
             format_bytes(e.per_rop_bytes), format_bytes(e.shared_bytes), e.total_bytes);
  for (const MemoryTerm& t : e.terms) {
    if (t.bytes == 0) continue;
    std::string keys;
    for (const std::string& k : t.keys) keys += (keys.empty() ? "" : ", ") + k;
    fmt::print("#   {:<24} {:>10}{}  {}\n", t.name, format_bytes(t.bytes),
               t.per_rop_bytes ? fmt::format(" ({} a ROP)", format_bytes(t.per_rop_bytes)) : std::string(),
               keys.empty() ? std::string("(the screen)") : keys);
  }
  fmt::print("#   approximate model: {}\n", format_bytes(approx.total_bytes));
  const MemoryBudget& b = memory_budget();
  if (b.limit() != 0 && e.total_bytes > b.limit()) {
    std::string keys;
    for (const std::string& k : e.costliest_keys()) keys += (keys.empty() ? "" : ", ") + k;
    fmt::print("#   over --memory-limit {}: a cycle run of this design is refused; the keys that cost the most: {}\n",
               format_bytes(b.limit()), keys);
  }
}

int cmd_config(const ConfigOpts& o) {
  if (o.markdown) {
    std::fputs(hw_params_markdown().c_str(), stdout);
    return 0;
  }
  if (o.silicon_check) return print_silicon_check();
  const HwConfig c = resolve_hw_config(o.file, o.hw_sets);
  if (o.silicon) return print_silicon(c, o);
  const MemoryShape shape = shape_of(o);
  const MemoryEstimate cycle = estimate_memory(c, shape, MemoryModel::kCycle);
  const MemoryEstimate approx = estimate_memory(c, shape, MemoryModel::kApproximate);
  if (o.json) {
    nlohmann::ordered_json j = hw_config_to_json(c);
    j["memory_estimate"] = estimate_to_json(cycle, approx);
    fmt::print("{}\n", j.dump(2));
    return 0;
  }
  fmt::print("# ropsim hardware config: {}\n", c.name);
  for (const auto& a : c.overrides) fmt::print("# --hw-set {}\n", a);
  fmt::print("{}", hw_config_to_toml(c));
  print_estimate(cycle, approx);
  return 0;
}

}  // namespace

VerbRunner add_config_command(CLI::App& app) {
  auto o = std::make_shared<ConfigOpts>();
  CLI::App* cfgc =
      app.add_subcommand("config", "Print the hardware config (defaults or a file, resolved) or its parameter table");
  cfgc->add_option("FILE", o->file, "Config file to check and print resolved (default: the built-in defaults)")
      ->check(CLI::ExistingFile);
  cfgc->add_option("--hw-set", o->hw_sets, "Override one parameter, section.key=value; repeatable (as for run)");
  cfgc->add_flag("--json", o->json, "Print the resolved design as JSON: section -> key -> typed value");
  auto* md = cfgc->add_flag("--markdown", o->markdown,
                            "Print every parameter with unit, default, range and meaning (docs/config.md)");
  md->excludes(cfgc->get_option("--json"));
  md->excludes(cfgc->get_option("--hw-set"));
  auto* si = cfgc->add_flag("--silicon", o->silicon,
                            "Print the silicon cost of the design's LK units (docs/rtl.md \"Cost of a design\")");
  cfgc->add_option("--spp", o->spp,
                   "Samples per pixel of the run the silicon cost and memory estimate assume (default 16)");
  cfgc->add_option("--width", o->width,
                   "Screen width in pixels the silicon cost and memory estimate assume (default 1024)")
      ->check(in_range(1, 32768));
  cfgc->add_option("--height", o->height,
                   "Screen height in pixels the silicon cost and memory estimate assume (default 1024)")
      ->check(in_range(1, 32768));
  auto* sc = cfgc->add_flag("--silicon-check", o->silicon_check,
                            "Print each cost model's largest error on the sweep rows held out from its fit");
  si->excludes(cfgc->get_option("--json"));
  si->excludes(md);
  sc->excludes(si);
  sc->excludes(md);
  cfgc->footer(examples({"ropsim config configs/narrow.toml", "ropsim config --markdown",
                         "ropsim config configs/wide.toml --hw-set numerics.hash_bits=16 --json"}));
  return [o, cfgc]() { return cfgc->parsed() ? cmd_config(*o) : -1; };
}

}  // namespace ropsim
