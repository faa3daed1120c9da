#include "sim/cli/run_outputs.h"

#include <fmt/format.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>

#include "rtl_models/algo/slab.h"
#include "rtl_models/config/hw_config.h"
#include "rtl_models/top/memory_estimate.h"
#include "sim/cli/cli_common.h"
#include "sim/fidelity/cycle/cycle_run.h"
#include "sim/fidelity/fidelity.h"
#include "sim/fidelity/functional/driver.h"
#include "sim/fidelity/run.h"
#include "sim/fidelity/sampled/livepoint_file.h"
#include "sim/image/heat_map.h"
#include "sim/image/image_io.h"
#include "sim/report/cycle_report.h"
#include "sim/report/report.h"
#include "sim/report/run_report.h"
#include "traces/format/trace.h"
#include "util/host_threads.h"

namespace ropsim::cli {

void add_breakdown_outputs(const RunOpts& o, const RunBreakdown* b, bool with_cycles, const Image& image,
                           const std::optional<Image>& reference, std::vector<TextOutput>& texts,
                           uint32_t dram_listed) {
  if (!b) return;
  if (!o.draw_csv.empty()) texts.push_back(TextOutput{o.draw_csv, draws_csv(*b, with_cycles, dram_listed)});
  if (o.maps.empty()) return;
  const uint32_t w = b->width(), h = b->height();
  auto add = [&](const std::string& name, const std::string& unit, const MapRows& rows, double max) {
    const std::string base = (std::filesystem::path(o.maps) / name).string();
    const auto exr = encode_heat_exr(w, h, rows, base + ".exr");
    const auto png = encode_heat_png(w, h, rows, max, HeatLabels{name, unit}, base + ".png");
    texts.push_back(TextOutput{base + ".exr", std::string(exr.begin(), exr.end())});
    texts.push_back(TextOutput{base + ".png", std::string(png.begin(), png.end())});
  };
  for (size_t i = 0; i < pixel_map_descs().size(); ++i) {
    const PixelMap m = PixelMap(i);
    add(
        pixel_map_descs()[i].name, std::string(pixel_map_descs()[i].unit) + " per pixel",
        [b, m](uint32_t y, float* out) { b->row(m, y, out); }, double(b->max(m)));
  }
  if (reference) {
    std::vector<float> a(size_t(w) * 3), r(a.size());
    auto rows = [&](uint32_t y, float* out) {
      image.row(y, a.data());
      reference->row(y, r.data());
      for (uint32_t x = 0; x < w; ++x) {
        double s = 0;
        for (int c = 0; c < 3; ++c) {
          const double d = double(a[3 * x + c]) - double(r[3 * x + c]);
          s += d * d;
        }
        out[x] = float(std::sqrt(s / 3.0) * 255.0);
      }
    };
    float max = 0;
    std::vector<float> row(w);
    for (uint32_t y = 0; y < h; ++y) {
      rows(y, row.data());
      for (float v : row) max = std::max(max, v);
    }
    add("error", "8-bit units", rows, double(max));
  }
}

void add_tile_maps(const RunOpts& o, const CycleRun& run, std::vector<TextOutput>& texts) {
  const Attribution* a = run.tiles.get();
  if (!a || o.maps.empty()) return;
  const uint32_t tx = run.tiles_x, ty = run.tiles_y, tp = run.stats.hw.distributor.tile_pixels;
  const uint32_t w = run.header.width, h = run.header.height;
  for (size_t i = 0; i < tile_map_descs().size(); ++i) {
    const StatDesc& m = tile_map_descs()[i];
    const std::vector<uint64_t>& v = tile_map(*a, i);
    uint64_t max = 0;
    for (uint64_t x : v) max = std::max(max, x);
    const std::string base = (std::filesystem::path(o.maps) / m.name).string();
    const auto exr = encode_heat_exr(
        tx, ty,
        [&](uint32_t y, float* out) {
          for (uint32_t x = 0; x < tx; ++x) out[x] = float(v[size_t(y) * tx + x]);
        },
        base + ".exr");
    const auto png = encode_heat_png(
        w, h,
        [&](uint32_t y, float* out) {
          for (uint32_t x = 0; x < w; ++x) out[x] = float(v[size_t(y / tp) * tx + x / tp]);
        },
        double(max), HeatLabels{m.name, std::string(m.unit) + " per tile"}, base + ".png");
    texts.push_back(TextOutput{base + ".exr", std::string(exr.begin(), exr.end())});
    texts.push_back(TextOutput{base + ".png", std::string(png.begin(), png.end())});
  }
}

std::string gtkw_path(const std::string& vcd) {
  std::filesystem::path p(vcd);
  if (p.extension() == ".gtkw") return vcd + ".gtkw";
  return p.replace_extension(".gtkw").string();
}

std::string default_output_base(const RunOpts& o, const InputSpec& in, int spp, const GoldenConfig& cfg,
                                const HwConfig& hw) {
  std::string base;
  if (in.from_trace()) {
    base = std::filesystem::path(in.trace_path).stem().string();
  } else {
    const SceneParams& sp = in.scene;
    base = sp.name;
    if (sp.width || sp.height) {
      uint32_t w = sp.width, h = sp.height;
      for (const auto& c : scene_catalog())
        if (c.name == sp.name) {
          if (!w) w = c.width;
          if (!h) h = c.height;
        }
      base += fmt::format("-{}x{}", w, h);
    }
    if (sp.seed != SceneParams{}.seed) base += fmt::format("-seed{}", sp.seed);
  }
  base = fmt::format("out/run/{}-{}-{}spp", base, to_string(cfg.method), spp);
  if (in.repeat > 1) base += fmt::format("-x{}", in.repeat);
  if (cfg.method == Method::kSlab) base += fmt::format("-k{}b{}", cfg.slab_layers, cfg.slab_bits);
  // Distinct designs never share a name: a timed run adds a digest of the
  // resolved design (numerics included), a functional run its numerics when
  // they are not the defaults.
  const Numerics& n = cfg.numerics;
  if (const Fidelity f = fidelity_of(o); is_timed(f))
    base += fmt::format("-{}-hw{}", to_string(f), hw_digest_hex(hw));
  else if (n.hash_bits != Numerics{}.hash_bits || n.alpha_bits != Numerics{}.alpha_bits ||
           n.surface_id_bits != Numerics{}.surface_id_bits)
    base += fmt::format("-h{}a{}s{}", n.hash_bits, n.alpha_bits, n.surface_id_bits);
  return base;
}

std::vector<std::string> map_files(const RunOpts& o, bool cycle) {
  std::vector<std::string> names;
  for (const auto& d : pixel_map_descs()) names.push_back(d.name);
  if (o.vs_reference) names.push_back("error");
  if (cycle)
    for (const auto& d : tile_map_descs()) names.push_back(d.name);
  std::vector<std::string> files;
  for (const auto& n : names)
    for (const char* ext : {".exr", ".png"}) files.push_back((std::filesystem::path(o.maps) / n).string() + ext);
  return files;
}

void check_outputs(const RunOpts& o, const std::vector<std::string>& outs, const std::string& report, bool cycle) {
  const bool defaults = o.outs.empty() && o.report.empty();
  OutputPlan plan;
  plan.input("--trace", o.trace);
  plan.input("--livepoints", o.livepoints);
  plan.input("--hw", o.hw);
  for (const auto& p : outs) plan.output(defaults ? "the default image" : "--out", p);
  plan.output(defaults ? "the default report" : "--report", report);
  plan.output("--vcd", o.vcd);
  if (!o.vcd.empty()) plan.output("--vcd's GTKWave save file", gtkw_path(o.vcd));
  plan.output("--stats-csv", o.stats_csv);
  plan.output("--draw-csv", o.draw_csv);
  if (!o.maps.empty()) {
    plan.output("--maps", o.maps);
    for (const auto& f : map_files(o, cycle)) plan.output("--maps", f);
  }
  plan.check();
}

}  // namespace ropsim::cli
