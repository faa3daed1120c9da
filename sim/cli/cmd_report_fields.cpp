// `ropsim report-fields`: every report field with its unit and meaning, from
// the declarations of the report printers; --markdown as the table of
// docs/reports.md.
#include <fmt/format.h>

#include <cstdio>
#include <memory>

#include "sim/cli/cli_common.h"
#include "sim/report/cycle_report.h"

namespace ropsim {

VerbRunner add_report_fields_command(CLI::App& app) {
  auto markdown = std::make_shared<bool>(false);
  CLI::App* c = app.add_subcommand("report-fields", "List every report field with its unit and meaning");
  c->add_flag("--markdown", *markdown, "As the Markdown table of docs/reports.md");
  c->footer(examples({"ropsim report-fields", "ropsim report-fields --markdown"}));
  return [markdown, c]() {
    if (!c->parsed()) return -1;
    const auto docs = report_field_docs();
    if (*markdown) {
      std::fputs(fields_markdown(docs).c_str(), stdout);
    } else {
      for (const auto& d : docs) fmt::print("{:<50} {:<12} {}\n", d.path, d.unit, d.meaning);
    }
    return 0;
  };
}

}  // namespace ropsim
