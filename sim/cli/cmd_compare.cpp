// `ropsim compare A B`: RMSE and PSNR of image A against image B.
#include <fmt/format.h>

#include <cmath>
#include <memory>

#include "cli_common.h"
#include "image_io.h"

namespace ropsim {

namespace {

struct CompareOpts {
  std::string a, b;
  bool json = false;
};

int cmd_compare(const CompareOpts& o) {
  CompareResult c = compare_image_files(o.a, o.b);
  if (o.json)
    fmt::print(
        "{{\"rmse_8bit\": {:.6f}, \"psnr_db\": {:.4f}, \"max_error_8bit\": {:.6f}, \"mean_error_8bit\": {:.6f}}}\n",
        c.rmse_8bit, std::isfinite(c.psnr_db) ? c.psnr_db : 999.0, c.max_error_8bit, c.mean_error_8bit);
  else
    fmt::print("RMSE {:.4f} (8-bit units)  PSNR {:.2f} dB  max error {:.2f}\n", c.rmse_8bit, c.psnr_db,
               c.max_error_8bit);
  return 0;
}

}  // namespace

VerbRunner add_compare_command(CLI::App& app) {
  auto o = std::make_shared<CompareOpts>();
  CLI::App* cmp = app.add_subcommand("compare", "RMSE (8-bit units) and PSNR of image A against image B");
  cmp->add_option("A", o->a, "Image")->required()->check(CLI::ExistingFile);
  cmp->add_option("B", o->b, "Reference image")->required()->check(CLI::ExistingFile);
  cmp->add_flag("--json", o->json, "Print JSON");
  return [o, cmp]() { return cmp->parsed() ? cmd_compare(*o) : -1; };
}

}  // namespace ropsim
