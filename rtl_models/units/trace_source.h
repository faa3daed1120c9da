// Trace source: models the rasterizer-to-ROP interface. Pulls fragments from
// a FragmentSource (a trace being read, or a scene) and delivers up to fragments_per_clock per
// clock into its FIFO, in API order. It touches no timed shared state, so it
// may run decoupled (unit.h): then it fills its FIFO ahead of SystemC time and
// refills it the moment the distributor frees a slot.
#pragma once
#include <exception>
#include <functional>

#include "rtl_models/config/hw_config.h"
#include "rtl_models/core/pipe_unit.h"
#include "rtl_models/functional/fragment_source.h"
#include "rtl_models/units/rop_ownership.h"

namespace ropsim {

class TraceSource : public DecoupledUnit {
 public:
  TraceSource(const sc_core::sc_module_name& name, const Clock& clk, FragmentSource& input, FunctionalRop& rop,
              TokenPool& pool, const HwConfig::Source& cfg, TokenFifo& out, const RopOwnership& tiles);
  void start_of_simulation() override { wake_at(0); }
  /// An exception the input threw (bad record), rethrown after sc_start.
  std::exception_ptr error() const { return error_; }
  /// The input has no more fragments; `produced` were delivered.
  bool done() const { return done_; }
  uint64_t produced() const { return seq_; }
  /// Called every kProgressEvery fragments with the count so far and the
  /// share of the input consumed (FragmentSource::consumed).
  std::function<void(uint64_t produced, double consumed)> on_progress;
  static constexpr uint64_t kProgressEvery = 1 << 16;
  /// Issue counting tokens (FragToken::counting: a breakdown is collected).
  void set_counting(bool on) { counting_ = on; }

 protected:
  void advance(uint64_t limit) override;

 private:
  FragmentSource& input_;
  FunctionalRop& rop_;
  TokenPool& pool_;
  HwConfig::Source cfg_;
  TokenFifo& out_;
  RopOwnership tiles_;  // the distributor's screen tiles (FragToken::tile)
  uint64_t seq_ = 0;
  bool counting_ = false;
  uint64_t t_ = 0;  // the clock being decided
  uint32_t n_ = 0;  // fragments already delivered in it
  bool done_ = false;
  std::exception_ptr error_;
};

}  // namespace ropsim
