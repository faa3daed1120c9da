// `ropsim scene NAME -o TRACE`: write a built-in scene as a trace; --list.
#include <fmt/format.h>

#include <memory>

#include "sim/cli/cli_common.h"
#include "traces/format/trace.h"

namespace ropsim {

namespace {

struct SceneOpts {
  SceneParams sp;
  std::string out, depth_mode = "plane", color_fmt = "rgb-f32", compression = "zstd";
  bool list = false, no_checksum = false;
};

int cmd_scene(SceneOpts& o, const CLI::App& sub) {
  if (o.list) {
    for (const auto& s : scene_catalog())
      fmt::print("{:<13} {:>4}x{:<4} {}\n", s.name, s.width, s.height, s.description);
    return 0;
  }
  if (!sub.count("NAME")) throw UserError("scene: give a scene NAME (or --list)");
  if (o.out.empty()) throw UserError("scene: give -o FILE");
  SceneParams sp = o.sp;
  sp.depth_mode = o.depth_mode == "plane" ? DepthMode::kPlane : DepthMode::kPerSample;
  sp.color_format = o.color_fmt == "rgb-f32" ? ColorFormat::kRgbF32 : ColorFormat::kRgbUnorm8;
  sp.compression = o.compression == "zstd" ? Compression::kZstd : Compression::kNone;
  sp.checksum = !o.no_checksum;
  ensure_parent_dir(o.out);
  RasterStats st = write_scene_trace(sp, o.out);
  fmt::print("wrote {}: {} triangles, {} fragments, {} covered samples\n", o.out, st.triangles, st.fragments,
             st.covered_samples);
  return 0;
}

}  // namespace

VerbRunner add_scene_command(CLI::App& app) {
  auto o = std::make_shared<SceneOpts>();
  CLI::App* scn = app.add_subcommand("scene", "Write a built-in scene as a trace file, or list the scenes");
  scn->add_option("NAME", o->sp.name, "Scene: " + join(scene_names()))->check(CLI::IsMember(scene_names()));
  scn->add_option("--spp", o->sp.spp, "Samples per pixel: 1, 2, 4, 8, 16, 32 or 64 (default 16)")
      ->check(CLI::IsMember({1, 2, 4, 8, 16, 32, 64}));
  scn->add_option("-o,--out,--output", o->out, "Trace file to write")->type_name("FILE");
  scn->add_option("--width", o->sp.width, "Width in pixels (default: the scene's)")
      ->check(in_range(1u, kMaxScreenSide));
  scn->add_option("--height", o->sp.height, "Height in pixels (default: the scene's)")
      ->check(in_range(1u, kMaxScreenSide));
  scn->add_option("--seed", o->sp.seed, "Scene generator seed (default 1)");
  scn->add_option("--depth", o->depth_mode, "Depth records: plane or per-sample (default plane)")
      ->check(CLI::IsMember({"plane", "per-sample"}));
  scn->add_option("--color", o->color_fmt, "Colour records: rgb-f32 or rgb-unorm8 (default rgb-f32)")
      ->check(CLI::IsMember({"rgb-f32", "rgb-unorm8"}));
  scn->add_option("--compression", o->compression, "zstd or none (default zstd)")
      ->check(CLI::IsMember({"zstd", "none"}));
  scn->add_flag("--no-checksum", o->no_checksum,
                "Write the payload without checksum records (header flag 0; docs/trace-format.md 2.3)");
  scn->add_flag("--list", o->list, "List the built-in scenes");
  scn->footer(examples({"ropsim scene --list", "ropsim scene cloth --spp 4 -o cloth.trace",
                        "ropsim scene cloth --spp 4 --no-checksum -o plain.trace"}));
  return [o, scn]() { return scn->parsed() ? cmd_scene(*o, *scn) : -1; };
}

}  // namespace ropsim
