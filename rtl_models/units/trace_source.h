// Trace source: models the rasterizer-to-ROP interface. Pulls fragments (a
// trace being read, or a scene) and delivers up to fragments_per_clock per
// clock into its FIFO, in API order.
#pragma once
#include <exception>
#include <functional>

#include "hw_config.h"
#include "pipe_unit.h"

namespace ropsim {

class TraceSource : public Unit {
 public:
  /// Fills the fragment and returns true, or returns false at the end.
  using Supplier = std::function<bool(Fragment&)>;
  TraceSource(const sc_core::sc_module_name& name, const Clock& clk, RopContext& ctx, const HwConfig::Source& cfg,
              Supplier supplier, TokenFifo& out);
  void start_of_simulation() override { wake_at(0); }
  /// An exception the supplier threw (bad record), rethrown after sc_start.
  std::exception_ptr error() const { return error_; }
  /// Called every progress_every fragments with the count so far.
  std::function<void(uint64_t)> on_progress;
  static constexpr uint64_t kProgressEvery = 1 << 16;

 protected:
  void step(uint64_t now) override;

 private:
  RopContext& ctx_;
  HwConfig::Source cfg_;
  Supplier supplier_;
  TokenFifo& out_;
  uint64_t seq_ = 0, busy_until_ = 0;
  bool done_ = false;
  std::exception_ptr error_;
};

}  // namespace ropsim
