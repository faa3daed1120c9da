// `ropsim compare A B`: RMSE and PSNR of image A against image B, in linear
// light (an sRGB PNG is converted; docs/reports.md).
#include <fmt/format.h>

#include <cmath>
#include <memory>

#include "sim/cli/cli_common.h"
#include "sim/image/image_io.h"

namespace ropsim {

namespace {

struct CompareOpts {
  std::string a, b;
  bool json = false;
};

int cmd_compare(const CompareOpts& o) {
  const FileComparison fc = compare_image_files(o.a, o.b);
  const CompareResult& c = fc.result;
  // Identical images: PSNR is infinite (JSON has no infinity: null).
  const bool finite = std::isfinite(c.psnr_db);
  if (o.json) {
    fmt::print(
        "{{\"rmse_8bit\": {:.6f}, \"psnr_db\": {}, \"max_error_8bit\": {:.6f}, \"mean_error_8bit\": {:.6f}, "
        "\"compared_in\": \"linear\", \"a_transfer\": \"{}\", \"b_transfer\": \"{}\"}}\n",
        c.rmse_8bit, finite ? fmt::format("{:.4f}", c.psnr_db) : std::string("null"), c.max_error_8bit,
        c.mean_error_8bit, to_string(fc.a), to_string(fc.b));
  } else {
    std::string conv;
    if (fc.a == Transfer::kSrgb) conv += fmt::format("; {} converted from sRGB", o.a);
    if (fc.b == Transfer::kSrgb) conv += fmt::format("; {} converted from sRGB", o.b);
    fmt::print("RMSE {:.4f} (8-bit units, linear)  PSNR {} dB  max error {:.2f}{}\n", c.rmse_8bit,
               finite ? fmt::format("{:.2f}", c.psnr_db) : std::string("inf"), c.max_error_8bit, conv);
  }
  return 0;
}

}  // namespace

VerbRunner add_compare_command(CLI::App& app) {
  auto o = std::make_shared<CompareOpts>();
  CLI::App* cmp = app.add_subcommand(
      "compare", "RMSE (8-bit units) and PSNR of image A against image B, in linear light (an sRGB PNG is converted)");
  cmp->add_option("A", o->a, "Image")->required()->check(CLI::ExistingFile);
  cmp->add_option("B", o->b, "Reference image")->required()->check(CLI::ExistingFile);
  cmp->add_flag("--json", o->json, "Print JSON");
  cmp->footer(examples({"ropsim compare lk.exr reference.exr",
                        "ropsim compare lk.png reference.exr   # a PNG (sRGB) against an EXR, in linear light",
                        "ropsim compare lk.exr reference.exr --json"}));
  return [o, cmp]() { return cmp->parsed() ? cmd_compare(*o) : -1; };
}

}  // namespace ropsim
