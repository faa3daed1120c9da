#include "sim/fidelity/run.h"

#include "util/errors.h"

namespace ropsim {

namespace {

template <class... F>
struct Overload : F... {
  using F::operator()...;
};
template <class... F>
Overload(F...) -> Overload<F...>;

}  // namespace

Fidelity RunResult::fidelity() const {
  return std::visit(Overload{[](const FunctionalRun&) { return Fidelity::kFunctional; },
                             [](const CycleRun&) { return Fidelity::kCycle; },
                             [](const SampledResult&) { return Fidelity::kSampled; },
                             [](const ApproxRun&) { return Fidelity::kApproximate; }},
                    run_);
}

const TraceHeader& RunResult::header() const {
  return std::visit(Overload{[](const SampledResult& s) -> const TraceHeader& { return s.library->header; },
                             [](const auto& r) -> const TraceHeader& { return r.header; }},
                    run_);
}

const Counters& RunResult::counters() const {
  return std::visit(Overload{[](const SampledResult& s) -> const Counters& { return s.library->counters; },
                             [](const auto& r) -> const Counters& { return r.counters; }},
                    run_);
}

const Image& RunResult::image() const {
  return std::visit(Overload{[](const SampledResult& s) -> const Image& { return s.library->image; },
                             [](const auto& r) -> const Image& { return r.image; }},
                    run_);
}

size_t RunResult::state_bytes() const {
  return std::visit(
      Overload{[](const SampledResult&) -> size_t { return 0; }, [](const auto& r) { return r.state_bytes; }}, run_);
}

double RunResult::wall_seconds() const {
  return std::visit([](const auto& r) { return r.wall_seconds; }, run_);
}

const std::optional<Image>& RunResult::reference() const {
  if (const FunctionalRun* f = functional()) return f->reference;
  return reference_;
}

void RunResult::set_reference(std::optional<Image> reference) {
  if (FunctionalRun* f = functional())
    f->reference = std::move(reference);
  else
    reference_ = std::move(reference);
}

RunResult run_fidelity(const RunRequest& r) {
  switch (r.fidelity) {
    case Fidelity::kFunctional:
      return RunResult(run_functional(r.input, r.method));
    case Fidelity::kCycle:
      return RunResult(run_cycle(r.input, r.method, r.hw));
    case Fidelity::kApproximate:
      return RunResult(run_approximate(r.input, r.method, r.hw));
    case Fidelity::kSampled: {
      invariant(r.library != nullptr, "a sampled run request names its live-point library");
      SampledResult s;
      s.library = r.library;
      s.run = run_sampled(*r.library, r.hw, r.jobs);
      s.hw = r.hw;
      s.from = r.from;
      s.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - r.started).count();
      return RunResult(std::move(s));
    }
  }
  throw InternalError("run_fidelity: a fidelity without a run");
}

}  // namespace ropsim
