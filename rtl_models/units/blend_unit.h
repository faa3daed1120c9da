// Blend unit (the blend passes of wboit, alpha correction and depth-based
// accumulation, and blend's framebuffer pass): the functional ROP's blend
// stage (multiplicative into the transmittance target, additive into the
// accumulation target, blend.h; blend: the draw's blend into the framebuffer
// and its depth write, framebuffer_blend.h) and the render-target (and
// depth) writes through the ROP cache. The destination was read
// with the depth at the depth test (read-modify-write); samples_per_clock
// blends per clock; after the latency the fragment retires and its pixel
// leaves the scoreboard. Its cache writes are posted (PostedWrites,
// rop_cache.h), so it touches no timed state at its own cycle and runs
// decoupled (unit.h), like the writeback it replaces in those passes.
#pragma once
#include "rtl_models/config/hw_config.h"
#include "rtl_models/core/pipe_unit.h"
#include "rtl_models/memory/address_map.h"
#include "rtl_models/memory/rop_cache.h"

namespace ropsim {

class BlendUnit : public DecoupledUnit {
 public:
  BlendUnit(const sc_core::sc_module_name& name, const Clock& clk, FunctionalRop& rop, Retirement& retirement,
            const AddressMap& amap, const HwConfig::Blend& cfg, RopCache& cache, TokenFifo& in);
  std::vector<Extra> extras() const override {
    return {{"samples_blended", double(blended_), "samples", "samples blended into the render targets"}};
  }

 protected:
  void advance(uint64_t limit) override;

 private:
  /// The blend stage and its cache writes; returns the samples blended.
  uint32_t process(FragToken* t, uint64_t now);
  FunctionalRop& rop_;
  Retirement& retirement_;
  const AddressMap& amap_;
  HwConfig::Blend cfg_;
  RopCache& cache_;
  TokenFifo& in_;
  uint64_t busy_until_ = 0, blended_ = 0;
  bool closed_ = false;
};

/// The render targets a blend pass reads and writes (none for other passes).
inline bool pass_blends_transmittance(PassKind p) { return p == PassKind::kTotalAlpha || p == PassKind::kWboit; }
/// (blend's framebuffer pass: the accumulation target holds the framebuffer.)
inline bool pass_blends_accum(PassKind p) {
  return p == PassKind::kAccumulate || p == PassKind::kWboit || p == PassKind::kFramebuffer;
}

}  // namespace ropsim
