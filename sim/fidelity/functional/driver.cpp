#include "sim/fidelity/functional/driver.h"

#include <chrono>
#include <fstream>

#include "rtl_models/functional/pass_loop.h"
#include "util/errors.h"
#include "util/host_threads.h"
#include "util/memory_budget.h"
#include "util/progress.h"

namespace ropsim {

FragmentList load_fragments(const InputSpec& in) {
  FragmentList out;
  auto src = open_fragments(in);
  out.header = src->header();
  for (Fragment f; src->next(f);) out.fragments.push_back(f);
  return out;
}

void check_reference_estimate(const FragmentSource& src) {
  if (const uint64_t n = src.fragments_at_least(); n > 0)
    memory_budget().check_estimate(n * ReferenceModel::kBytesPerFragmentAtLeast,
                                   "the A-buffer reference of at least " + std::to_string(n) + " fragments");
}

FunctionalRun run_functional(const InputSpec& spec, const GoldenConfig& cfg, bool with_reference, int threads,
                             const BreakdownRequest& breakdown) {
  const auto t0 = std::chrono::steady_clock::now();
  FunctionalRun run;
  // The trace's decoder takes a core of its own only where the model's
  // threads leave one spare.
  InputSpec in = spec;
  in.decode_ahead = spec.decode_ahead && (threads > 0 ? threads : host_threads()) < available_cores();
  auto src = open_fragments(in);
  run.header = src->header();
  if (with_reference || cfg.method == Method::kReference) check_reference_estimate(*src);
  std::unique_ptr<FunctionalModel> model = make_functional_model(run.header, cfg, threads), ref;
  if (with_reference && cfg.method != Method::kReference) {
    GoldenConfig ref_cfg = cfg;
    ref_cfg.method = Method::kReference;
    ref = make_functional_model(run.header, ref_cfg);
  }
  // In batches: while the model draws one (on its threads), this thread
  // reads the next and runs the reference over the current one.
  constexpr size_t kBatch = 4096;
  std::vector<Fragment> cur(kBatch), next(kBatch);
  // The breakdown: each fragment's counter delta, recorded by index on the
  // lanes' threads, added in API order on this one after the batch.
  std::vector<Counters> deltas;
  if (breakdown.any()) {
    auto* sm = dynamic_cast<StochasticModel*>(model.get());
    if (!sm) throw UserError("--per-draw and --maps need a method with a ROP (not the reference)");
    run.breakdown = std::make_unique<RunBreakdown>(run.header, breakdown.per_draw, breakdown.per_pixel);
    deltas.resize(kBatch);
    sm->set_counts_observer([&deltas](size_t i, const FragWork&, const Counters& d) { deltas[i] = d; });
  }
  Progress progress(cfg.method == Method::kReference ? "reference" : "functional", "fragments");
  uint64_t read = 0;
  int pass = 0, passes = 1;
  auto fill = [&](std::vector<Fragment>& b) {
    size_t n = 0;
    while (n < b.size() && src->next(b[n])) ++n;
    read += n;
    progress.update(pass_progress(pass, passes, src->consumed()), read);
    return n;
  };
  for_each_pass(
      *model, src, [&] { return open_fragments(in); },
      [&](int p, int n_passes) {
        pass = p;
        passes = n_passes;
        FunctionalModel* r = pass == 0 ? ref.get() : nullptr;
        for (size_t n = fill(cur), n_next = 0; n > 0; n = n_next) {
          model->draw_batch(cur.data(), n, [&] {
            if (r)
              for (size_t i = 0; i < n; ++i) r->draw(cur[i]);
            n_next = fill(next);
          });
          if (RunBreakdown* b = run.breakdown.get())
            for (size_t i = 0; i < n; ++i) b->add(cur[i], deltas[i]);
          cur.swap(next);
        }
      });
  progress.update(1.0, read);
  progress.finish();
  run.image = model->resolve();
  run.counters = model->counters();
  run.kind_fragments = model->kind_fragments();
  run.state_bytes = model->state_bytes();
  if (auto* sm = dynamic_cast<const StochasticModel*>(model.get())) run.threads = sm->threads();
  if (ref) run.reference = ref->resolve();
  if (cfg.compression.any())
    if (auto* sm = dynamic_cast<const StochasticModel*>(model.get()))
      run.compression = measure_compressibility(sm->store(), cfg.compression);
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
