// Pixel ordering: a scoreboard of the pixels in flight in one ROP unit, from
// issue to retire. A fragment issues only when no earlier fragment of its
// pixel is in flight or waiting, so fragments of one pixel retire in trace
// order (the surface tracker and the depth test depend on it), while a
// fragment of another pixel in the window may overtake a blocked one.
// One fragment issues per clock.
#pragma once
#include <utility>
#include <vector>

#include "rtl_models/config/hw_config.h"
#include "rtl_models/core/pipe_unit.h"
#include "util/containers/flat_set.h"
#include "util/containers/sorted_ring.h"

namespace ropsim {

class PixelOrdering : public Unit, public PixelRelease {
 public:
  PixelOrdering(const sc_core::sc_module_name& name, const Clock& clk, const HwConfig::Ordering& cfg, TokenFifo& in,
                TokenFifo& out);
  /// The fragment of this pixel retires at the given cycle (>= now): from the
  /// next cycle on another fragment of the pixel may issue.
  void release(uint64_t pixel_key, uint64_t cycle) override;
  std::vector<Extra> extras() const override;

 protected:
  void step(uint64_t now) override;

 private:
  HwConfig::Ordering cfg_;
  TokenFifo& in_;
  TokenFifo& out_;
  std::vector<FragToken*> window_;
  FlatSet in_flight_;
  struct EarlierRelease {
    bool operator()(const std::pair<uint64_t, uint64_t>& a, const std::pair<uint64_t, uint64_t>& b) const {
      return a.first < b.first;
    }
  };
  SortedRing<std::pair<uint64_t, uint64_t>, EarlierRelease> releases_;  // (cycle, pixel), by cycle
  uint64_t busy_until_ = 0;
  bool seen_ = false, waiting_release_ = false;
  uint64_t overtakes_ = 0, max_in_flight_ = 0;
};

}  // namespace ropsim
