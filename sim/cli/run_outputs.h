// What `ropsim run` writes: the images, the report, the per-draw CSV and
// the heat maps, staged and committed all or none, and their default names.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "sim/cli/run_options.h"
#include "sim/fidelity/cycle/cycle_run.h"
#include "sim/image/image_io.h"
#include "sim/report/report.h"
#include "util/output_file.h"

namespace ropsim::cli {

/// A text output staged beside the images (the --stats-interval CSV, the
/// --draw-csv table, a --maps image: text holds any bytes).
struct TextOutput {
  std::string path, text;
};

/// The breakdown's outputs: the per-draw CSV, and per map an EXR and a PNG
/// in the --maps folder (the error against the reference too, when there is
/// one: per-pixel RMSE over R, G, B in 8-bit units).
void add_breakdown_outputs(const RunOpts& o, const RunBreakdown* b, bool with_cycles, const Image& image,
                           const std::optional<Image>& reference, std::vector<TextOutput>& texts,
                           uint32_t dram_listed = 0);

/// The cycle model's per-tile maps (--maps; attribution.h): per distributor
/// tile, an EXR with one pixel per tile (so each sums to its report counter)
/// and a screen-sized PNG (each tile's value over its pixels, to lay over the
/// frame).
void add_tile_maps(const RunOpts& o, const CycleRun& run, std::vector<TextOutput>& texts);

/// Writes the images and the report, all or none: every output is staged in
/// its own temporary file first, then all are committed (renamed). A failure
/// while staging leaves nothing; main removes outputs this run created (e.g.
/// a waveform) when it fails. report_text is called after the images are
/// staged, so it can list them. A report to "-" (stdout) is written last.
template <class ReportText>
void write_outputs(ReportContext& ctx, const Image& image, const std::vector<std::string>& outs,
                   const std::string& report, ReportText report_text, const std::vector<TextOutput>& texts = {}) {
  std::vector<std::unique_ptr<OutputFile>> staged;
  for (const auto& p : outs) {
    const std::vector<unsigned char> bytes = encode_image(image, p);
    ensure_parent_dir(p);
    staged.push_back(std::make_unique<OutputFile>(p));
    staged.back()->write(bytes.data(), bytes.size());
    ctx.outputs.push_back(p);
  }
  for (const auto& t : texts) {
    ensure_parent_dir(t.path);
    staged.push_back(std::make_unique<OutputFile>(t.path));
    staged.back()->write(t.text);
    ctx.outputs.push_back(t.path);
  }
  std::unique_ptr<OutputFile> rep;
  if (!report.empty()) {
    ensure_parent_dir(report);
    OutputFile::Options o;
    o.allow_stdout = true;
    rep = std::make_unique<OutputFile>(report, o);
    if (!rep->to_stdout()) ctx.outputs.push_back(report);
    const std::string text = report_text() + "\n";
    if (!rep->to_stdout()) rep->write(text);
    for (auto& f : staged) f->commit();
    if (rep->to_stdout()) rep->write(text);
    rep->commit();
    return;
  }
  for (auto& f : staged) f->commit();
}

/// The GTKWave save file beside the waveform: its name with .gtkw for its extension.
std::string gtkw_path(const std::string& vcd);

/// The default outputs' name, out/run/BASE.{png,exr,json} (docs/outputs.md
/// "Default names"): the input replayed (a trace file's stem, or a scene's
/// name with the parameters that change it), its spp and the method, then
/// what else makes two runs' results differ: the slab's k and b, the
/// fidelity and the design's digest, or a functional run's non-default
/// numerics.
std::string default_output_base(const RunOpts& o, const InputSpec& in, int spp, const GoldenConfig& cfg,
                                const HwConfig& hw);

/// The --maps folder's files a run writes (add_breakdown_outputs,
/// add_tile_maps): per map an EXR and a PNG.
std::vector<std::string> map_files(const RunOpts& o, bool cycle);

/// Refuses, before any work, two outputs of the run that are one file (the
/// same name, a link, an implied file) and an output that is an input.
void check_outputs(const RunOpts& o, const std::vector<std::string>& outs, const std::string& report, bool cycle);

}  // namespace ropsim::cli
