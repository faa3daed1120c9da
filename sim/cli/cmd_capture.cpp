#include "sim/cli/cmd_capture.h"

#include <fmt/format.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>

#include "sim/cli/cli_common.h"
#include "traces/capture/capture.h"
#include "traces/capture/scene_file.h"
#include "util/output_file.h"
#ifdef ROPSIM_HAVE_OSMESA
#include "traces/capture/mesa_capture.h"
#endif

namespace ropsim {

namespace {

struct CaptureOpts {
  std::string scene, out, mesh_dir, order;
  int spp = 0;
  uint32_t width = 0, height = 0;
  uint64_t seed = 0;
  bool allow_empty = false, quiet = false, cross_check = false, no_checksum = false, progress = false;
};

int run_capture(const CaptureOpts& o, const CLI::App& sub) {
  if (o.scene.empty())
    throw CaptureError("capture: give SCENE (a scene file), or `capture gl` for an OpenGL application");
  set_progress_flags(o.quiet, o.progress);
  SceneOverrides ov;
  if (sub.count("--mesh-dir")) ov.mesh_dir = o.mesh_dir;
  if (sub.count("--spp")) ov.spp = o.spp;
  if (sub.count("--width")) ov.width = o.width;
  if (sub.count("--height")) ov.height = o.height;
  if (sub.count("--seed")) ov.seed = o.seed;
  if (sub.count("--order")) {
    DrawOrder d;
    parse_draw_order(o.order, d);
    ov.order = d;
  }
  SceneSpec spec = load_scene_file(o.scene, ov);
  spec.checksum = !o.no_checksum;
  if (o.cross_check) {
#ifdef ROPSIM_HAVE_OSMESA
    const CrossCheckResult r = cross_check_with_mesa(spec);
    std::fputs(cross_check_summary(r).c_str(), stdout);
    return 0;
#else
    throw CaptureError("--cross-check: this ropsim was built without OSMesa (install libosmesa6-dev)");
#endif
  }
  if (o.out.empty()) throw CaptureError("capture: give -o TRACE");
  OutputPlan plan;
  plan.input("SCENE", o.scene);
  plan.output("-o", o.out);
  plan.check();
  ensure_parent_dir(o.out);
  CaptureStats st;
  {
    Progress bar("capture", "triangles");
    st = capture_to_file(spec, o.out, o.allow_empty,
                         [&](uint64_t d, uint64_t t) { bar.update(t ? double(d) / double(t) : -1.0, d); });
    bar.update(1.0, st.triangles);
    bar.finish();
  }
  if (!o.quiet)
    fmt::print(
        "wrote {}: {}x{} {} spp, {} triangles ({} outside, {} clipped, {} back-facing, {} discarded), "
        "{} fragments, {} covered samples, {:.2f} s ({:.2f} M fragments/s)\n",
        o.out, spec.width, spec.height, spec.spp, st.triangles, st.outside, st.clipped, st.back_facing, st.discarded,
        st.fragments, st.covered_samples, st.seconds, st.seconds > 0 ? double(st.fragments) / st.seconds / 1e6 : 0.0);
  return 0;
}

}  // namespace

std::function<int()> add_capture_command(CLI::App& app) {
  auto o = std::make_shared<CaptureOpts>();
  CLI::App* sub = app.add_subcommand(
      "capture", "Rasterize a mesh scene file (OBJ / glTF meshes, camera, opacity; docs/capture.md) into a trace");
  // Required unless the `gl` subcommand is given (checked in run_capture).
  sub->add_option("SCENE", o->scene, "Scene file (TOML)");
  sub->add_option("-o,--out,--output", o->out,
                  "Trace file to write (written atomically: no file on error; docs/outputs.md)")
      ->type_name("FILE");
  sub->add_option(
      "--mesh-dir", o->mesh_dir,
      "Folder to look for the scene's meshes in first (default: $ROPSIM_MESH_DIR), then the scene's mesh_dir");
  sub->add_option("--spp", o->spp, "Override the scene's samples per pixel: 1, 2, 4, 8, 16, 32 or 64")
      ->check(CLI::IsMember({1, 2, 4, 8, 16, 32, 64}));
  sub->add_option("--width", o->width, "Override the scene's width in pixels")->check(in_range(1u, 32768u));
  sub->add_option("--height", o->height, "Override the scene's height in pixels")->check(in_range(1u, 32768u));
  sub->add_option("--seed", o->seed, "Override the scene's shuffle seed");
  sub->add_option("--order", o->order, "Override every object's draw order")
      ->check(CLI::IsMember({"authored", "shuffled", "far-to-near", "near-to-far"}));
  sub->add_flag("--no-checksum", o->no_checksum,
                "Write the payload without checksum records (header flag 0; docs/trace-format.md 2.3)");
  sub->add_flag("--allow-empty", o->allow_empty, "Write a trace even when nothing is visible (else an error)");
  sub->add_flag("--cross-check", o->cross_check,
                "Instead of writing a trace, capture the scene at 4 spp through Mesa (llvmpipe) and through ropsim "
                "with Mesa's sample positions, and print how the records agree");
  sub->add_flag("--quiet", o->quiet, "Print nothing on success");
  sub->add_flag("--progress", o->progress,
                "Show progress (share of the triangles, rate, ETA) even when stderr is not a terminal: a line every "
                "5 s, for logs");
  sub->footer(examples({"ropsim capture traces/scenes/mesh/cloth.toml --width 128 --height 128 --spp 4 -o mesh.trace",
                        "ropsim capture traces/scenes/mesh/cloth.toml --width 128 --height 128 --order far-to-near "
                        "-o sorted.trace"}));
  const std::function<int()> gl = add_capture_gl_command(*sub);
  CLI::App* gl_sub = sub->get_subcommand("gl");
  return [o, sub, gl, gl_sub]() {
    if (!sub->parsed()) return -1;
    return gl_sub->parsed() ? gl() : run_capture(*o, *sub);
  };
}

}  // namespace ropsim
