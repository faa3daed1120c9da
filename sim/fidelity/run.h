// A run of any fidelity: what it is asked (RunRequest), what it gives
// (RunResult: the header, counters, image and state every fidelity gives,
// with the timing of a timed one and the estimate of a sampled one), and the
// one entry that runs it. A study's points run through run_fidelity; the CLI
// runs each fidelity with its own outputs (waveforms, maps, interval CSV) and
// wraps the result the same way, so sim/report prints every run through one
// printer (run_report.h).
#pragma once
#include <chrono>
#include <optional>
#include <variant>

#include "rtl_models/config/hw_config.h"
#include "rtl_models/functional/fragment_source.h"
#include "rtl_models/functional/image.h"
#include "sim/fidelity/approximate/approximate.h"
#include "sim/fidelity/cycle/cycle_run.h"
#include "sim/fidelity/fidelity.h"
#include "sim/fidelity/functional/driver.h"
#include "sim/fidelity/sampled/livepoints.h"

namespace ropsim {

/// A sampled run: its estimates, on a library of live-points that outlives
/// the result, and the design they were simulated on.
struct SampledResult {
  const LivePoints* library = nullptr;
  SampledRun run;
  HwConfig hw;
  LibrarySource from;       ///< where the live-points came from
  double wall_seconds = 0;  ///< the library's reading or recording included
};

class RunResult {
 public:
  explicit RunResult(FunctionalRun r) : run_(std::move(r)) {}
  explicit RunResult(CycleRun r) : run_(std::move(r)) {}
  explicit RunResult(SampledResult r) : run_(std::move(r)) {}
  explicit RunResult(ApproxRun r) : run_(std::move(r)) {}

  Fidelity fidelity() const;
  const TraceHeader& header() const;
  const Counters& counters() const;
  const Image& image() const;
  /// Bytes of the final per-sample state the run kept (0 for a sampled run:
  /// the library's).
  size_t state_bytes() const;
  /// Host time of the whole run: input, model and resolve.
  double wall_seconds() const;
  /// The reference method's image, when the run was compared with it.
  const std::optional<Image>& reference() const;
  void set_reference(std::optional<Image> reference);

  /// The fidelity's own result (null for the others).
  const FunctionalRun* functional() const { return std::get_if<FunctionalRun>(&run_); }
  const CycleRun* cycle() const { return std::get_if<CycleRun>(&run_); }
  const SampledResult* sampled() const { return std::get_if<SampledResult>(&run_); }
  const ApproxRun* approximate() const { return std::get_if<ApproxRun>(&run_); }
  FunctionalRun* functional() { return std::get_if<FunctionalRun>(&run_); }
  CycleRun* cycle() { return std::get_if<CycleRun>(&run_); }

 private:
  std::variant<FunctionalRun, CycleRun, SampledResult, ApproxRun> run_;
  std::optional<Image> reference_;  // the timed fidelities' (a functional run keeps its own)
};

struct RunRequest {
  Fidelity fidelity = Fidelity::kFunctional;
  InputSpec input;
  GoldenConfig method;
  HwConfig hw;                          ///< timed fidelities: the design
  const LivePoints* library = nullptr;  ///< sampled: the live-points (required; outlives the result)
  LibrarySource from;                   ///< sampled: where they came from
  int jobs = 1;                         ///< sampled: worker processes simulating the units
  /// The wall time counts from here (a sampled run: before its library was
  /// read or recorded).
  std::chrono::steady_clock::time_point started = std::chrono::steady_clock::now();
};

/// Runs the request's fidelity with its default options. Throws UserError
/// for what the fidelity refuses (e.g. the reference method in a timed one).
RunResult run_fidelity(const RunRequest& r);

}  // namespace ropsim
