// `ropsim config [FILE]`: print the hardware config resolved, or --markdown
// the parameter table (docs/config.md).
#include <fmt/format.h>

#include <cstdio>
#include <memory>

#include "cli_common.h"
#include "hw_config.h"

namespace ropsim {

namespace {

struct ConfigOpts {
  std::string file;
  bool markdown = false;
};

int cmd_config(const ConfigOpts& o) {
  if (o.markdown) {
    std::fputs(hw_params_markdown().c_str(), stdout);
    return 0;
  }
  HwConfig c = o.file.empty() ? HwConfig{} : load_hw_config(o.file);
  fmt::print("# ropsim hardware config: {}\n{}", c.name, hw_config_to_toml(c));
  return 0;
}

}  // namespace

VerbRunner add_config_command(CLI::App& app) {
  auto o = std::make_shared<ConfigOpts>();
  CLI::App* cfgc =
      app.add_subcommand("config", "Print the hardware config (defaults or a file, resolved) or its parameter table");
  cfgc->add_option("FILE", o->file, "Config file to check and print resolved (default: the built-in defaults)")
      ->check(CLI::ExistingFile);
  cfgc->add_flag("--markdown", o->markdown,
                 "Print every parameter with unit, default, range and meaning (docs/config.md)");
  return [o, cfgc]() { return cfgc->parsed() ? cmd_config(*o) : -1; };
}

}  // namespace ropsim
