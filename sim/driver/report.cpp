#include "report.h"

#include <fmt/format.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "image_io.h"
#include "output_file.h"
#include "version.h"

namespace ropsim {

nlohmann::ordered_json counters_to_json(const Counters& c) {
  nlohmann::ordered_json j;
  j["fragments"] = c.fragments;
  j["samples_tested"] = c.samples_tested;
  j["samples_depth_passed"] = c.samples_depth_passed;
  j["samples_opacity_passed"] = c.samples_opacity_passed;
  j["samples_written"] = c.samples_written;
  j["surface_id_changes"] = c.surface_id_changes;
  j["sorts"] = c.sorts;
  j["depth_bytes_read"] = c.depth_bytes_read;
  j["depth_bytes_written"] = c.depth_bytes_written;
  j["color_bytes_written"] = c.color_bytes_written;
  j["tracker_bytes_read"] = c.tracker_bytes_read;
  j["tracker_bytes_written"] = c.tracker_bytes_written;
  j["state_bytes_read"] = c.depth_bytes_read + c.tracker_bytes_read;
  j["state_bytes_written"] = c.depth_bytes_written + c.color_bytes_written + c.tracker_bytes_written;
  j["tiles_touched"] = c.tiles_touched;
  return j;
}

nlohmann::ordered_json numerics_to_json(const Numerics& n) {
  nlohmann::ordered_json j;
  j["hash_bits"] = n.hash_bits;
  j["alpha_bits"] = n.alpha_bits;
  j["surface_id_bits"] = n.surface_id_bits;
  return j;
}

nlohmann::ordered_json functional_report(const ReportContext& ctx, const FunctionalRun& run) {
  nlohmann::ordered_json j;
  j["tool"] = "ropsim";
  j["ropsim"] = {{"version", ropsim_version()}, {"commit", ropsim_commit()}};
  j["report_version"] = 1;
  j["command"] = ctx.command_line;
  j["fidelity"] = "functional";
  nlohmann::ordered_json in;
  if (ctx.input.from_trace()) {
    in["trace"] = ctx.input.trace_path;
  } else {
    in["scene"] = ctx.input.scene.name;
    in["scene_seed"] = ctx.input.scene.seed;
  }
  in["scene_name"] = run.header.scene_name;
  in["width"] = run.header.width;
  in["height"] = run.header.height;
  in["spp"] = run.header.spp;
  j["input"] = in;
  j["method"] = to_string(ctx.config.method);
  j["seed"] = ctx.config.seed;
  j["numerics"] = numerics_to_json(ctx.config.numerics);
  j["counters"] = counters_to_json(run.counters);
  nlohmann::ordered_json host;
  host["wall_seconds"] = run.wall_seconds;
  host["samples_per_second"] = run.wall_seconds > 0 ? double(run.counters.samples_tested) / run.wall_seconds : 0.0;
  host["fragments_per_second"] = run.wall_seconds > 0 ? double(run.counters.fragments) / run.wall_seconds : 0.0;
  host["state_bytes"] = run.state_bytes;
  host["peak_rss_bytes"] = peak_rss_bytes();
  j["host"] = host;
  if (run.reference) {
    CompareResult c = compare_images(run.image, *run.reference);
    j["vs_reference"] = {{"rmse_8bit", c.rmse_8bit}, {"psnr_db", std::isfinite(c.psnr_db) ? c.psnr_db : 999.0},
                         {"max_error_8bit", c.max_error_8bit}};
  }
  j["outputs"] = ctx.outputs;
  return j;
}

std::string functional_summary(const ReportContext& ctx, const FunctionalRun& run) {
  const Counters& c = run.counters;
  std::string s = fmt::format("ropsim: {} | method {} | {}x{} @ {} spp\n", ctx.input.describe(),
                              to_string(ctx.config.method), run.header.width, run.header.height, run.header.spp);
  s += fmt::format("  fragments {}  samples tested {}  depth-passed {}  written {}\n", c.fragments, c.samples_tested,
                   c.samples_depth_passed, c.samples_written);
  if (ctx.config.method == Method::kLk)
    s += fmt::format("  surface-id changes {}  sorts {}\n", c.surface_id_changes, c.sorts);
  s += fmt::format("  state traffic: {} B read, {} B written; {} tiles touched\n", c.depth_bytes_read + c.tracker_bytes_read,
                   c.depth_bytes_written + c.color_bytes_written + c.tracker_bytes_written, c.tiles_touched);
  s += fmt::format("  wall {:.3f} s, {:.1f} M samples/s\n", run.wall_seconds,
                   run.wall_seconds > 0 ? c.samples_tested / run.wall_seconds / 1e6 : 0.0);
  if (run.reference) {
    CompareResult cr = compare_images(run.image, *run.reference);
    s += fmt::format("  vs reference: RMSE {:.3f} (8-bit units), PSNR {:.2f} dB\n", cr.rmse_8bit, cr.psnr_db);
  }
  for (const auto& o : ctx.outputs) s += "  wrote " + o + "\n";
  return s;
}

void write_text_file_atomic(const std::string& path, const std::string& text) { write_text_output(path, text); }

}  // namespace ropsim
