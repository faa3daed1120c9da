// Writeback: the opacity test (lk: alpha >= reference, in the fixed-point
// rule of opacity.h) and the conditional depth and colour writes through the
// ROP cache. samples_per_clock tests and writes per clock; after the latency
// the fragment retires and its pixel leaves the scoreboard. Its cache writes
// are posted (PostedWrites, rop_cache.h), so it touches no timed state at its
// own cycle and may run decoupled (unit.h).
#pragma once
#include "rtl_models/config/hw_config.h"
#include "rtl_models/core/pipe_unit.h"
#include "rtl_models/memory/address_map.h"
#include "rtl_models/memory/rop_cache.h"

namespace ropsim {

class Writeback : public DecoupledUnit {
 public:
  Writeback(const sc_core::sc_module_name& name, const Clock& clk, FunctionalRop& rop, Retirement& retirement,
            const AddressMap& amap, const HwConfig::Writeback& cfg, RopCache& cache, TokenFifo& in);
  std::vector<Extra> extras() const override {
    return {{"samples_written", double(written_), "samples", "samples whose depth and colour were written"}};
  }

 protected:
  void advance(uint64_t limit) override;

 private:
  /// The write stage and its cache writes; returns the samples it examined.
  uint32_t process(FragToken* t, uint64_t now);
  FunctionalRop& rop_;
  Retirement& retirement_;
  const AddressMap& amap_;
  HwConfig::Writeback cfg_;
  RopCache& cache_;
  TokenFifo& in_;
  uint64_t busy_until_ = 0, written_ = 0;
  bool closed_ = false;
};

}  // namespace ropsim
