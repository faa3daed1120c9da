#include "alpha_ref_gen.h"

namespace ropsim {

PipeUnit::Timing AlphaRefGen::process(FragToken* t, uint64_t) {
  const uint32_t hashes = run_stage(rop_.reference(), *t);
  stats_.samples += hashes;
  const uint32_t interval = std::max<uint32_t>(1, ceil_div(hashes, cfg_.lanes));
  return {interval, cfg_.pipeline_depth + interval - 1};
}

}  // namespace ropsim
