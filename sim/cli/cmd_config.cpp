// `ropsim config [FILE] [--hw-set K=V]... [--json]`: print the hardware design
// resolved (as TOML, or --json as section -> key -> value), or --markdown the
// parameter table (docs/config.md).
#include <fmt/format.h>

#include <cstdio>
#include <memory>

#include "cli_common.h"
#include "cycle_report.h"
#include "hw_config.h"

namespace ropsim {

namespace {

struct ConfigOpts {
  std::string file;
  std::vector<std::string> hw_sets;
  bool markdown = false, json = false;
};

int cmd_config(const ConfigOpts& o) {
  if (o.markdown) {
    std::fputs(hw_params_markdown().c_str(), stdout);
    return 0;
  }
  const HwConfig c = resolve_hw_config(o.file, o.hw_sets);
  if (o.json) {
    fmt::print("{}\n", hw_config_to_json(c).dump(2));
    return 0;
  }
  fmt::print("# ropsim hardware config: {}\n", c.name);
  for (const auto& a : c.overrides) fmt::print("# --hw-set {}\n", a);
  fmt::print("{}", hw_config_to_toml(c));
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
  return [o, cfgc]() { return cfgc->parsed() ? cmd_config(*o) : -1; };
}

}  // namespace ropsim
