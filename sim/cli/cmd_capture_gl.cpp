// `ropsim capture gl`: the command line of the GL capture (gl_capture.h):
// its options, an application entry (--app), the frame's list and the
// capture's summary.
#include <fmt/format.h>

#include <cstdio>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>

#include "sim/cli/cli_common.h"
#include "sim/cli/cmd_capture.h"
#include "traces/capture/app_entry.h"
#include "traces/glcapture/gl_capture.h"
#include "util/child_process.h"
#include "util/errors.h"

namespace ropsim {

namespace {

using nlohmann::json;

struct GlCaptureOpts : GlCaptureRequest {
  std::string app_file;
  bool json = false, quiet = false;
};

std::string plural(uint64_t n, const char* one, const char* many) {
  return fmt::format("{} {}", n, n == 1 ? one : many);
}

/// The framebuffers and draws of list.json as two tables.
void print_list(const json& list, const GlCaptureOpts& o, const std::string& what) {
  auto table = [](const std::vector<std::string>& head, const std::vector<std::vector<std::string>>& rows) {
    std::vector<size_t> w(head.size());
    for (size_t c = 0; c < head.size(); ++c) w[c] = head[c].size();
    for (const auto& r : rows)
      for (size_t c = 0; c < r.size() && c < w.size(); ++c) w[c] = std::max(w[c], r[c].size());
    auto line = [&](const std::vector<std::string>& r) {
      std::string s = " ";
      for (size_t c = 0; c < r.size(); ++c)
        s += " " + r[c] + (c + 1 < r.size() ? std::string(w[c] - r[c].size(), ' ') : "");
      fmt::print("{}\n", s);
    };
    line(head);
    for (const auto& r : rows) line(r);
  };
  std::vector<std::vector<std::string>> fbs, draws;
  const json empty = json::array();
  for (const auto& f : list.value("framebuffers", empty))
    fbs.push_back({json_field<std::string>(f, "name", "?"),
                   fmt::format("{}x{}", json_field<uint64_t>(f, "width", 0), json_field<uint64_t>(f, "height", 0)),
                   std::to_string(json_field<uint64_t>(f, "samples", 0)), json_field<std::string>(f, "encoding", "?"),
                   std::to_string(json_field<uint64_t>(f, "draws", 0)),
                   json_field<bool>(f, "presented", false) ? "yes" : "no"});
  for (const auto& d : list.value("draws", empty)) {
    const auto passed = d.find("samples_passed");
    draws.push_back({std::to_string(json_field<uint64_t>(d, "index", 0)),
                     json_field<std::string>(d, "framebuffer", "?"),
                     std::to_string(json_field<uint64_t>(d, "program", 0)), json_field<std::string>(d, "name", ""),
                     json_field<std::string>(d, "kind", "?"), json_field<std::string>(d, "blend", ""),
                     json_field<std::string>(d, "depth", ""), std::to_string(json_field<uint64_t>(d, "fragments", 0)),
                     std::to_string(json_field<uint64_t>(d, "covered_samples", 0)),
                     passed != d.end() && passed->is_number() ? std::to_string(passed->get<uint64_t>()) : "-"});
  }
  fmt::print("frame {} of {}: {}\n", o.frame, what, plural(fbs.size(), "framebuffer", "framebuffers"));
  table({"framebuffer", "size", "samples", "encoding", "draws", "presented"}, fbs);
  fmt::print("{}\n", plural(draws.size(), "draw", "draws"));
  if (!draws.empty())
    table({"draw", "framebuffer", "program", "name", "kind", "blend", "depth", "fragments", "covered", "passed"},
          draws);
}

int run_capture_gl(GlCaptureOpts o, const CLI::App& sub) {
  if (o.json && !o.list) throw UserError("capture gl: --json goes with --list");
  if (!o.app_file.empty()) {
    if (!o.app.empty() || !o.apitrace.empty())
      throw UserError("capture gl: --app names the application: give no application after -- and no --apitrace");
    AppOverrides ov;
    if (sub.count("--spp")) ov.spp = o.spp;
    if (sub.count("--width")) ov.width = o.width;
    if (sub.count("--height")) ov.height = o.height;
    if (sub.count("--frame")) ov.frame = o.frame;
    const AppEntry e = load_app_entry(o.app_file, ov);
    o.app = app_command(e);
    o.frame = e.frame;
    o.spp = e.spp;
    o.width = e.width;
    o.height = e.height;
    if (!sub.count("--target")) o.target = e.target;
    if (!sub.count("--timeout")) o.timeout = e.timeout;
    o.what = e.path;
    o.package = e.package;
  } else if (!sub.count("--frame")) {
    throw UserError("capture gl: give --frame N (or --app FILE, whose entry names the frame)");
  }
  StopSignals signals;
  const GlCaptureResult r = run_gl_capture(o, &signals);
  const json& status = r.status;
  const json& list = r.list;
  const std::string& what = r.what;
  if (o.list) {
    if (o.json)
      fmt::print("{}\n", list.dump(2));
    else
      print_list(list, o, what);
    return 0;
  }
  const uint64_t bytes = r.bytes;
  // The summary: what went into the trace, and every draw that did not.
  const json unsupported = status.value("unsupported", json::array());
  std::set<uint64_t> left_out;
  for (const auto& u : unsupported) left_out.insert(json_field<uint64_t>(u, "draw", 0));
  std::map<std::string, uint64_t> kinds;  // of the draws in the trace: into the target, captured
  const std::string tname = gl_target_name(json_field<std::string>(status, "target", o.target));
  for (const auto& d : list.value("draws", json::array()))
    if (json_field<std::string>(d, "framebuffer", "") == tname && !left_out.count(json_field<uint64_t>(d, "index", 0)))
      ++kinds[json_field<std::string>(d, "kind", "other")];
  std::string by_kind;
  for (const char* k : {"opaque", "src-over", "premultiplied-over", "additive", "other"})
    if (kinds.count(k)) by_kind += (by_kind.empty() ? "" : ", ") + fmt::format("{} {}", kinds[k], k);
  // The draws not captured, consecutive draws of one name and reason as one
  // range ("draws 0-138").
  struct LeftOut {
    uint64_t first, last;
    std::string name, reason;
    std::string draws() const {
      return first == last ? fmt::format("draw {}", first) : fmt::format("draws {}-{}", first, last);
    }
  };
  std::vector<LeftOut> runs;
  for (const auto& u : unsupported) {
    const uint64_t d = json_field<uint64_t>(u, "draw", 0);
    const std::string name = json_field<std::string>(u, "name", "?"),
                      reason = json_field<std::string>(u, "reason", "?");
    if (!runs.empty() && runs.back().last + 1 == d && runs.back().name == name && runs.back().reason == reason)
      runs.back().last = d;
    else
      runs.push_back({d, d, name, reason});
  }
  for (const LeftOut& l : runs)
    std::fprintf(stderr, "ropsim: warning: %s: %s (%s) %s not in the trace: %s\n", what.c_str(), l.draws().c_str(),
                 l.name.c_str(), l.first == l.last ? "is" : "are", l.reason.c_str());
  if (!o.quiet) {
    const uint64_t draws = json_field<uint64_t>(status, "draws", 0);
    fmt::print("wrote {}: {} bytes, frame {} of {} ({} {}x{}), {} spp, {}{}, {} fragments", o.out, bytes, o.frame, what,
               tname, json_field<uint64_t>(status, "width", 0), json_field<uint64_t>(status, "height", 0),
               json_field<uint64_t>(status, "spp", uint64_t(o.spp)), plural(draws, "draw", "draws"),
               by_kind.empty() ? "" : " (" + by_kind + ")", json_field<uint64_t>(status, "fragments", 0));
    if (!unsupported.empty()) fmt::print(", {} not captured (unsupported)", unsupported.size());
    fmt::print("\n");
    for (const LeftOut& l : runs) fmt::print("  not captured: {} ({}): {}\n", l.draws(), l.name, l.reason);
  }
  return 0;
}

}  // namespace

std::function<int()> add_capture_gl_command(CLI::App& capture) {
  auto o = std::make_shared<GlCaptureOpts>();
  CLI::App* sub = capture.add_subcommand(
      "gl",
      "Capture one frame of an OpenGL application (run under a private Xvfb with Mesa llvmpipe, or an "
      "apitrace trace replayed by glretrace) into a trace with its draws' state (docs/capture.md)");
  sub->add_option("--frame", o->frame,
                  "The frame to capture: frames count from 0, frame N is the work after the N-th buffer swap "
                  "(required unless --app names it)")
      ->check(in_range<int64_t>(0))
      ->type_name("N");
  sub->add_option("-o,--out,--output", o->out,
                  "Trace file to write (written atomically: no file on error; docs/outputs.md)")
      ->type_name("FILE");
  sub->add_option("--spp", o->spp, "Samples per pixel of the trace: 1, 2, 4, 8, 16, 32 or 64")
      ->check(CLI::IsMember({1, 2, 4, 8, 16, 32, 64}));
  sub->add_option("--width", o->width, "Width of the virtual X screen in pixels (the application sizes its window)")
      ->check(in_range(16u, 16384u));
  sub->add_option("--height", o->height, "Height of the virtual X screen in pixels")->check(in_range(16u, 16384u));
  sub->add_option("--target", o->target,
                  "The framebuffer captured: presented (what the swap shows) or fbo:N (the framebuffer object named N)")
      ->check(CLI::Validator(
          [](std::string& t) -> std::string {
            if (t == "presented") return "";
            if (t.rfind("fbo:", 0) == 0 && t.size() > 4 && t.size() < 14 &&
                t.find_first_not_of("0123456789", 4) == std::string::npos && std::stoull(t.substr(4)) > 0)
              return "";
            return t + ": not presented or fbo:N (N >= 1, an FBO's GL name)";
          },
          "presented|fbo:N"));
  sub->add_option("--timeout", o->timeout,
                  "Seconds the application may take to reach the end of the frame; then it and its process group are "
                  "stopped and the capture fails")
      ->check(in_range(0.1, 1e6))
      ->type_name("SECONDS");
  sub->add_option("--app", o->app_file,
                  "Capture an application entry (traces/apps/NAME.toml: the command, frame, target, size and spp; "
                  "--frame, --spp, --width, --height, --target and --timeout override it)")
      ->type_name("FILE");
  sub->add_option("--apitrace", o->apitrace,
                  "Replay this apitrace trace with glretrace instead of running an application")
      ->type_name("FILE");
  sub->add_flag("--list", o->list,
                "Write no trace: list the frame's framebuffers and draws (index, framebuffer, program, kind, blend and "
                "depth state, fragments)");
  sub->add_flag("--json", o->json, "With --list: print the library's list (list.json) as JSON");
  sub->add_option("--keep-control", o->keep_control,
                  "Keep the capture library's files in this folder (created; must be empty): status.json, list.json, "
                  "frame.rgba + frame.json (the frame as the application rendered it), the application's and Xvfb's "
                  "output")
      ->type_name("DIR");
  sub->add_flag("--count-samples", o->count_samples,
                "Also count each draw's samples with an occlusion query (list.json's samples_passed; a cross-check)");
  sub->add_flag("--reference-msaa", o->reference_msaa,
                "Also render the frame's draws into a 4x MSAA copy of the target and keep the resolved image as "
                "frame-msaa4.rgba in --keep-control's folder (the reference at 4 spp)");
  sub->add_flag("--quiet", o->quiet, "Print nothing on success (warnings about draws not captured still go to stderr)");
  sub->add_option("APP", o->app, "The application and its arguments, after --")->type_name("ARGS");
  sub->footer(examples(
      {"ropsim capture gl --frame 5 --spp 4 -o jellyfish.trace -- glmark2 --size 128x128 -b jellyfish:duration=1",
       "ropsim capture gl --frame 5 --list -- glmark2 --size 128x128 -b pulsar:duration=1",
       "ropsim capture gl --apitrace app.trace --frame 10 -o app.trace.rop",
       "ropsim capture gl --app traces/apps/glmark2-jellyfish.toml --spp 16 -o jellyfish.rtr"}));
  return [o, sub]() { return run_capture_gl(*o, *sub); };
}

}  // namespace ropsim
