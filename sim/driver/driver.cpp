#include "driver.h"

#include <chrono>
#include <fstream>

namespace ropsim {

std::string InputSpec::describe() const {
  const std::string times = repeat > 1 ? ", drawn " + std::to_string(repeat) + " times" : "";
  if (from_trace()) return trace_path + times;
  return "scene " + scene.name + " at " + std::to_string(scene.spp) + " spp" + times;
}

void stream_fragments(const InputSpec& in, const std::function<void(const TraceHeader&)>& begin,
                      const std::function<void(const Fragment&)>& emit) {
  if (in.from_trace()) {
    for (uint32_t pass = 0; pass < in.repeat; ++pass) {
      TraceReader r(in.trace_path);
      if (pass == 0) begin(r.header());
      Fragment f;
      while (r.next(f)) emit(f);
    }
  } else {
    Scene s = build_scene(in.scene);
    begin(s.header);
    for (uint32_t pass = 0; pass < in.repeat; ++pass) rasterize_scene(s, emit);
  }
}

FragmentList load_fragments(const InputSpec& in) {
  FragmentList out;
  stream_fragments(in, [&](const TraceHeader& h) { out.header = h; },
                   [&](const Fragment& f) { out.fragments.push_back(f); });
  return out;
}

FunctionalRun run_functional(const InputSpec& in, const GoldenConfig& cfg, bool with_reference) {
  const auto t0 = std::chrono::steady_clock::now();
  FunctionalRun run;
  std::unique_ptr<FunctionalModel> model, ref;
  GoldenConfig ref_cfg = cfg;
  ref_cfg.method = Method::kReference;
  stream_fragments(
      in,
      [&](const TraceHeader& h) {
        run.header = h;
        model = make_functional_model(h, cfg);
        if (with_reference && cfg.method != Method::kReference) ref = make_functional_model(h, ref_cfg);
      },
      [&](const Fragment& f) {
        model->draw(f);
        if (ref) ref->draw(f);
      });
  run.image = model->resolve();
  run.counters = model->counters();
  run.state_bytes = model->state_bytes();
  if (ref) run.reference = ref->resolve();
  if (with_reference && cfg.method == Method::kReference) run.reference = run.image;
  run.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return run;
}

size_t peak_rss_bytes() {
  std::ifstream f("/proc/self/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("VmHWM:", 0) == 0) return size_t(std::stoull(line.substr(6))) * 1024;
  return 0;
}

}  // namespace ropsim
