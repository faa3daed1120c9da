// Distributor: routes each fragment to the ROP unit that owns its screen tile
// (square tiles of tile_pixels, mapped to units by the interleave), up to
// fragments_per_clock per clock, in order: a full ROP input FIFO blocks it.
// It touches no timed shared state, so it may run decoupled (unit.h).
#pragma once
#include <vector>

#include "rtl_models/algo/bits.h"
#include "rtl_models/config/hw_config.h"
#include "rtl_models/core/pipe_unit.h"
#include "rtl_models/units/rop_ownership.h"

namespace ropsim {

class Distributor : public DecoupledUnit {
 public:
  Distributor(const sc_core::sc_module_name& name, const Clock& clk, const HwConfig::Distributor& cfg,
              uint32_t screen_width, TokenFifo& in, std::vector<TokenFifo*> outs);
  /// The ROP unit owning pixel (x, y).
  uint32_t rop_of(uint32_t x, uint32_t y) const { return owner_.rop_of(x, y); }

 protected:
  void advance(uint64_t limit) override;

 private:
  HwConfig::Distributor cfg_;
  RopOwnership owner_;
  TokenFifo& in_;
  std::vector<TokenFifo*> outs_;
  uint64_t t_ = 0;  // the clock being decided
  uint32_t n_ = 0;  // fragments already routed in it
  bool seen_ = false, closed_ = false;
};

}  // namespace ropsim
