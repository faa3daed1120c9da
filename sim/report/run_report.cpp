#include "sim/report/run_report.h"

#include "sim/report/cycle_report.h"
#include "util/errors.h"

namespace ropsim {

nlohmann::ordered_json run_report(const ReportContext& ctx, const RunResult& run, FieldSink* sink) {
  switch (run.fidelity()) {
    case Fidelity::kFunctional:
      return functional_report(ctx, *run.functional(), sink);
    case Fidelity::kCycle:
      return cycle_report(ctx, *run.cycle(), run.reference(), sink);
    case Fidelity::kSampled: {
      const SampledResult& s = *run.sampled();
      return sampled_report(ctx, *s.library, s.run, s.hw, s.wall_seconds, s.from, run.reference(), sink);
    }
    case Fidelity::kApproximate:
      return approximate_report(ctx, *run.approximate(), run.reference(), sink);
  }
  throw InternalError("run_report: a fidelity without a report");
}

std::string run_summary(const ReportContext& ctx, const RunResult& run) {
  switch (run.fidelity()) {
    case Fidelity::kFunctional:
      return functional_summary(ctx, *run.functional());
    case Fidelity::kCycle:
      return cycle_summary(ctx, *run.cycle(), run.reference());
    case Fidelity::kSampled: {
      const SampledResult& s = *run.sampled();
      return sampled_summary(ctx, *s.library, s.run, s.hw, s.wall_seconds, s.from, run.reference());
    }
    case Fidelity::kApproximate:
      return approximate_summary(ctx, *run.approximate(), run.reference());
  }
  throw InternalError("run_summary: a fidelity without a summary");
}

}  // namespace ropsim
