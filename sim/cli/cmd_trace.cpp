// `ropsim trace info|validate|dump FILE`: inspect a trace file (info --json:
// the header and statistics as one JSON object).
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>

#include "sim/cli/cli_common.h"
#include "sim/driver/pixel_kinds.h"
#include "sim/fidelity/functional/driver.h"
#include "traces/format/frame_stats.h"
#include "traces/format/trace.h"
#include "util/containers/tile_map.h"

namespace ropsim {

namespace {

struct TraceOpts {
  std::string path, out = "-";
  uint64_t dump_limit = UINT64_MAX;
  bool json = false;
  std::vector<std::string> methods;
  uint64_t seed = 1;
};

int cmd_trace_info(const std::string& path, bool validate_only, bool json = false) {
  TraceReader r(path);
  Fragment f;
  uint64_t covered = 0;
  uint32_t max_draw = 0;
  // Depth complexity: fragments per touched pixel, in sparse 8x8 tiles.
  struct Counts {
    std::array<uint32_t, 64> n{};
  };
  TileMap<Counts> counts(r.header().width, r.header().height);
  FrameStatsCounter frame(r.header());
  const DrawTable& table = r.header().draws;
  while (r.next(f)) {
    covered += uint64_t(__builtin_popcountll(f.coverage));
    max_draw = std::max(max_draw, f.draw_id);
    if (validate_only) continue;
    ++counts.get(f.x, f.y, [](uint32_t, uint32_t) { return std::make_unique<Counts>(); })
          .n[(f.y & 7u) * 8 + (f.x & 7u)];
    frame.add(f);
  }
  const uint64_t n = r.records_read();
  if (validate_only) {
    const std::string draws =
        r.version() >= kTraceVersionDraws ? fmt::format(", {} draw states", table.size()) : std::string();
    if (r.header().checksummed)
      fmt::print("{}: valid, {} fragments{}, {} checksummed blocks verified\n", path, n, draws, r.blocks_read());
    else
      fmt::print("{}: valid, {} fragments{} (no checksum)\n", path, n, draws);
    return 0;
  }
  const FrameStats st = frame.finish();
  const auto& kind_draws = st.kind_draws;
  const auto& kind_fragments = st.kind_fragments;
  const auto& kind_covered = st.kind_covered;
  const auto& h = r.header();
  const auto file_bytes = std::filesystem::file_size(path);
  // The full histogram: touched pixels by their exact number of fragments.
  std::map<uint32_t, uint64_t> hist;
  uint64_t touched = 0, max_n = 0;
  counts.for_each([&](uint32_t, uint32_t, const Counts& c) {
    for (uint32_t k : c.n) {
      if (!k) continue;
      ++touched;
      ++hist[k];
      max_n = std::max<uint64_t>(max_n, k);
    }
  });
  const double per_frag = n ? double(covered) / n : 0.0;
  const double rec_per_frag = n ? double(r.payload_bytes()) / n : 0.0, disk_per_frag = n ? double(file_bytes) / n : 0.0;
  const double touched_pct = 100.0 * touched / (double(h.width) * h.height);
  const double mean_n = touched ? double(n) / touched : 0.0;
  if (json) {
    nlohmann::ordered_json j;
    j["file"] = path;
    j["header"] = nlohmann::ordered_json::parse(header_to_json(h));
    j["fragments"] = n;
    // The count the header records (null: not recorded); the reader held
    // the records to it.
    j["header_fragment_count"] =
        r.recorded_fragments() ? nlohmann::ordered_json(*r.recorded_fragments()) : nlohmann::ordered_json(nullptr);
    j["covered_samples"] = covered;
    j["covered_samples_per_fragment"] = per_frag;
    j["draws"] = n ? uint64_t(max_draw) + 1 : 0;
    j["bytes"] = {{"file", file_bytes},
                  {"records", r.payload_bytes()},
                  {"per_fragment_uncompressed", rec_per_frag},
                  {"per_fragment_on_disk", disk_per_frag}};
    j["checksum"] = h.checksummed ? nlohmann::ordered_json{{"hash", "xxh3-64"}, {"blocks", r.blocks_read()}}
                                  : nlohmann::ordered_json(nullptr);
    j["pixels_touched"] = touched;
    j["pixels_touched_percent"] = touched_pct;
    j["fragments_per_touched_pixel"] = {{"mean", mean_n}, {"max", max_n}};
    // Touched pixels by their exact number of fragments (every count that
    // occurs, ascending; the counts sum to pixels_touched).
    nlohmann::ordered_json hj = nlohmann::ordered_json::object();
    for (const auto& [k, c] : hist) hj[std::to_string(k)] = c;
    j["depth_complexity_histogram_pixels"] = hj;
    // Draws, fragments and covered samples by the draws' kind (DrawKind).
    nlohmann::ordered_json kj = nlohmann::ordered_json::object();
    for (int k = 0; k < kDrawKinds; ++k)
      kj[to_string(DrawKind(k))] = {{"draws", kind_draws[size_t(k)]},
                                    {"fragments", kind_fragments[size_t(k)]},
                                    {"covered_samples", kind_covered[size_t(k)]}};
    j["draw_kinds"] = kj;
    j["transparent"] = {{"kinds", {to_string(DrawKind::kSrcOver), to_string(DrawKind::kPremultipliedOver)}},
                        {"covered_samples", st.transparent_covered},
                        {"covered_samples_share", st.transparent_share()},
                        {"screen_samples_share", st.transparent_screen_share()},
                        {"translucent",
                         {{"fragments", st.translucent_fragments},
                          {"covered_samples", st.translucent_covered},
                          {"covered_samples_share", st.translucent_share()}}},
                        {"pixels", st.transparent_pixels},
                        {"fragments_per_pixel", {{"mean", st.transparent_per_pixel()}, {"max", st.transparent_max}}},
                        {"samples", st.transparent_samples},
                        {"fragments_per_covered_sample", {{"mean", st.transparent_per_sample()}}}};
    fmt::print("{}\n", j.dump(2));
    return 0;
  }
  fmt::print("{}\n  scene {}  {}x{}  {} spp\n  depth {}  colour {}  compression {}\n", path, h.scene_name, h.width,
             h.height, h.spp, to_string(h.depth_mode), to_string(h.color_format), to_string(h.compression));
  if (h.checksummed)
    fmt::print("  checksum xxh3-64, {} blocks verified\n", r.blocks_read());
  else
    fmt::print("  checksum none\n");
  fmt::print("  fragments {} ({} in the header)  covered samples {} ({:.2f} per fragment)  draws {}\n", n,
             r.recorded_fragments() ? "recorded" : "not recorded", covered, per_frag, n ? max_draw + 1 : 0);
  fmt::print("  bytes: file {}, records {} ({:.2f} per fragment uncompressed, {:.2f} on disk)\n", file_bytes,
             r.payload_bytes(), rec_per_frag, disk_per_frag);
  fmt::print("  pixels touched {} ({:.1f}% of the screen), fragments per touched pixel: mean {:.2f}, max {}\n", touched,
             touched_pct, mean_n, max_n);
  // Every count that occurs: fragments:pixels (share of the touched pixels),
  // wrapped.
  fmt::print("  depth complexity histogram (fragments: touched pixels, share), every count that occurs:\n");
  std::string line = "   ";
  for (const auto& [k, c] : hist) {
    const std::string item = fmt::format(" {}:{} ({:.2f}%)", k, c, 100.0 * double(c) / double(touched));
    if (line.size() + item.size() > 100) {
      fmt::print("{}\n", line);
      line = "   ";
    }
    line += item;
  }
  if (line.size() > 3) fmt::print("{}\n", line);
  fmt::print("  draws by kind ({}): draws, fragments, covered samples (share of all)\n",
             table.empty() ? "no draw states: every draw is src-over" : fmt::format("{} draw states", table.size()));
  for (int k = 0; k < kDrawKinds; ++k)
    fmt::print("    {:<19} {} draws, {} fragments, {} covered samples ({:.2f}%)\n", to_string(DrawKind(k)),
               kind_draws[size_t(k)], kind_fragments[size_t(k)], kind_covered[size_t(k)],
               covered ? 100.0 * double(kind_covered[size_t(k)]) / double(covered) : 0.0);
  fmt::print(
      "  transparent (src-over, premultiplied-over): {:.2f}% of the covered samples (at {:.2f}% of the screen's "
      "samples); {} pixels, fragments per pixel: mean {:.2f}, max {}; fragments per covered sample: mean {:.2f}\n",
      100.0 * st.transparent_share(), 100.0 * st.transparent_screen_share(), st.transparent_pixels,
      st.transparent_per_pixel(), st.transparent_max, st.transparent_per_sample());
  fmt::print(
      "    of them translucent (alpha below 1): {} fragments, {} covered samples, {:.2f}% of the covered samples\n",
      st.translucent_fragments, st.translucent_covered, 100.0 * st.translucent_share());
  return 0;
}

/// JSON lines to `out` ("-": standard output) through OutputFile.
int cmd_trace_dump(const std::string& path, const std::string& out_path, uint64_t limit) {
  OutputPlan plan;
  plan.input("FILE", path);
  plan.output("-o", out_path);
  plan.check();
  TraceReader r(path);
  ensure_parent_dir(out_path);
  OutputFile::Options o;
  o.allow_stdout = true;
  OutputFile out(out_path, o);
  out.write(header_to_json(r.header()) + '\n');
  Fragment f;
  uint64_t i = 0;
  while (i < limit && r.next(f)) out.write(fragment_to_json(r.header(), f, i++) + '\n');
  out.commit();
  return 0;
}

/// Pixels by kind (pixel_kinds.h), and each method's RMSE against the A-buffer
/// reference within each kind, as a Markdown table.
int cmd_trace_kinds(const std::string& path, const std::vector<std::string>& methods, uint64_t seed) {
  InputSpec in;
  in.trace_path = path;
  const PixelKinds k = classify_pixels(in);
  MethodConfig rc;
  rc.method = Method::kReference;
  const Image reference = run_functional(in, rc).image;
  std::vector<std::array<double, kPixelKinds>> rmse;
  for (const auto& name : methods) {
    MethodConfig m;
    if (!parse_method(name, m.method)) throw UserError("trace kinds: unknown method " + name);
    m.seed = seed;
    rmse.push_back(rmse_by_kind(k, run_functional(in, m).image, reference));
  }
  std::string head = "| pixel kind | pixels |", rule = "|---|---:|";
  for (const auto& name : methods) {
    head += " " + name + " RMSE |";
    rule += "---:|";
  }
  fmt::print("{}\n{}\n", head, rule);
  for (int j = 0; j < kPixelKinds; ++j) {
    if (!k.count[size_t(j)] || PixelKind(j) == PixelKind::kEmpty) continue;
    std::string row = fmt::format("| {} | {} |", to_string(PixelKind(j)), k.count[size_t(j)]);
    for (const auto& r : rmse) row += fmt::format(" {:.3f} |", r[size_t(j)]);
    fmt::print("{}\n", row);
  }
  return 0;
}

}  // namespace

VerbRunner add_trace_command(CLI::App& app) {
  auto o = std::make_shared<TraceOpts>();
  CLI::App* trc = app.add_subcommand("trace", "Inspect a trace file");
  trc->require_subcommand(1);
  trc->footer(examples({"ropsim trace info cloth.trace", "ropsim trace validate cloth.trace",
                        "ropsim trace dump cloth.trace --limit 5"}));
  CLI::App* tinfo = trc->add_subcommand("info", "Header and statistics (streams the whole trace)");
  tinfo->add_option("FILE", o->path, "Trace file")->required();
  tinfo->add_flag("--json", o->json, "Print the header and statistics as one JSON object");
  tinfo->footer(examples({"ropsim trace info cloth.trace", "ropsim trace info cloth.trace --json"}));
  CLI::App* tval = trc->add_subcommand("validate", "Check every record; exit 1 naming the first bad one");
  tval->add_option("FILE", o->path, "Trace file")->required();
  tval->footer(examples({"ropsim trace validate cloth.trace", "ropsim trace validate plain.trace"}));
  CLI::App* tdump = trc->add_subcommand("dump", "Header and fragments as JSON lines");
  tdump->add_option("FILE", o->path, "Trace file")->required();
  tdump->add_option("--limit", o->dump_limit, "Dump at most this many fragments (default: all; 0: the header alone)")
      ->check(in_range(uint64_t{0}))
      ->type_name("N");
  tdump->add_option("-o,--out,--output", o->out, "File to write (default -: standard output)")->type_name("FILE");
  tdump->footer(
      examples({"ropsim trace dump cloth.trace --limit 5",
                "ropsim trace dump cloth.trace --limit 0 -o header.jsonl   # the header line alone, to a file"}));
  CLI::App* tkinds = trc->add_subcommand("kinds", "Pixels by kind and each method's RMSE within each kind");
  tkinds->add_option("FILE", o->path, "Trace file")->required();
  tkinds
      ->add_option("--method", o->methods, "A method to compare with the reference; repeatable (default lk, enderton)")
      ->check(CLI::IsMember(method_names()));
  tkinds->add_option("--seed", o->seed, "Seed of the methods' hash-based random numbers (default 1)");
  tkinds->footer(examples(
      {"ropsim trace kinds cloth.trace", "ropsim trace kinds cloth.trace --method lk --method hashed --seed 7"}));
  return [o, tinfo, tval, tdump, tkinds]() {
    if (tkinds->parsed())
      return cmd_trace_kinds(o->path, o->methods.empty() ? std::vector<std::string>{"lk", "enderton"} : o->methods,
                             o->seed);
    if (tinfo->parsed()) return cmd_trace_info(o->path, false, o->json);
    if (tval->parsed()) return cmd_trace_info(o->path, true);
    if (tdump->parsed()) return cmd_trace_dump(o->path, o->out, o->dump_limit);
    return -1;
  };
}

}  // namespace ropsim
