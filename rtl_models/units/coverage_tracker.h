// Coverage bitmask tracker (lk only): LK Figure 7 lines 4-8 and 18 on the
// pixel's surface id and covered mask (track_surface / track_commit, shared
// with the golden model). A conflict with the covered mask starts a new
// surface; n = popcount(covered) indexes the alpha references. The updated
// state goes to the ROP cache with the fragment's writeback (writeback.h), so
// the tracker touches no timed state and may run decoupled. One fragment per
// clock.
#pragma once
#include "rtl_models/config/hw_config.h"
#include "rtl_models/core/pipe_unit.h"

namespace ropsim {

class CoverageTracker : public PipeUnit {
 public:
  CoverageTracker(const sc_core::sc_module_name& name, const Clock& clk, FunctionalRop& rop,
                  const HwConfig::Tracker& cfg, TokenFifo& in, TokenFifo& out)
      : PipeUnit(name, clk, rop, in, out), cfg_(cfg) {}
  std::vector<Extra> extras() const override {
    return {{"new_surfaces", double(new_surfaces_), "events", "bitmask conflicts that started a new surface"}};
  }

 protected:
  Timing process(FragToken* t, uint64_t now) override;

 private:
  HwConfig::Tracker cfg_;
  uint64_t new_surfaces_ = 0;
};

}  // namespace ropsim
