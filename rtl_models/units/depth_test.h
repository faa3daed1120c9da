// Depth test: loads the pixel's stored depths (and, for lk, its tracker
// state) through the ROP cache, computes the fragment's depth at each covered
// sample (plane_depth, as the golden model) and removes the samples that fail
// (z <= stored passes). Up to max_outstanding fragments wait for their data;
// the first whose data arrives leaves first (hit under miss), which is safe
// because pixel ordering never lets two fragments of one pixel be in flight.
// A fragment with no surviving sample retires here.
#pragma once
#include <vector>

#include "rtl_models/config/hw_config.h"
#include "rtl_models/core/pipe_unit.h"
#include "rtl_models/memory/address_map.h"
#include "rtl_models/memory/rop_cache.h"
#include "util/containers/sorted_ring.h"

namespace ropsim {

class DepthTest : public Unit {
 public:
  DepthTest(const sc_core::sc_module_name& name, const Clock& clk, FunctionalRop& rop, Retirement& retirement,
            const AddressMap& amap, const HwConfig::DepthTest& cfg, RopCache& cache, TokenFifo& in, TokenFifo& out);
  std::vector<Extra> extras() const override;
  /// A new fragment for a full unit waits for the run that frees a slot (an
  /// emission, always armed when full); a run for it alone would change
  /// nothing, so it is not asked for.
  void on_input(uint64_t visible) override {
    if (pending_.size() < cfg_.max_outstanding) wake_at(visible);
  }

 protected:
  void step(uint64_t now) override;

 private:
  /// The depth stage; returns the cycle the pixel's state is loaded.
  uint64_t evaluate(FragToken* t, uint64_t now);
  struct Pending {
    uint64_t ready, seq;
    FragToken* t;
    bool killed;  // no surviving sample (kept here: the token is cold by then)
    bool operator>(const Pending& o) const { return ready != o.ready ? ready > o.ready : seq > o.seq; }
  };
  FunctionalRop& rop_;
  Retirement& retirement_;
  const AddressMap& amap_;
  HwConfig::DepthTest cfg_;
  RopCache& cache_;
  TokenFifo& in_;
  TokenFifo& out_;
  /// Fragments waiting for their data, in (ready, seq) order; filled mostly
  /// at the back (ready cycles of successive misses increase).
  struct Earlier {
    bool operator()(const Pending& a, const Pending& b) const { return b > a; }
  };
  SortedRing<Pending, Earlier> pending_;
  uint64_t busy_until_ = 0;
  bool seen_ = false;
  uint64_t killed_ = 0;
};

}  // namespace ropsim
