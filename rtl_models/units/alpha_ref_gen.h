// Alpha-reference generator: the four-round multiply-xor hash. For lk it
// computes CalcAlphaRef(n + j, pixelId, surfaceId) for the j-th sorted
// survivor (pixelId = the Hilbert index of the pixel); for enderton it draws
// the sample count and the picks, for naive one random reference per survivor
// (the same hash, other inputs). lanes hashes per clock, pipeline_depth cycles.
#pragma once
#include "rtl_models/config/hw_config.h"
#include "rtl_models/core/pipe_unit.h"

namespace ropsim {

class AlphaRefGen : public PipeUnit {
 public:
  AlphaRefGen(const sc_core::sc_module_name& name, const Clock& clk, FunctionalRop& rop, const HwConfig::AlphaRef& cfg,
              TokenFifo& in, TokenFifo& out)
      : PipeUnit(name, clk, rop, in, out), cfg_(cfg) {}

 protected:
  Timing process(FragToken* t, uint64_t now) override;

 private:
  HwConfig::AlphaRef cfg_;
};

}  // namespace ropsim
