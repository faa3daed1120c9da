// The top of the cycle-approximate model: elaborates the pipeline for one
// pass of one input, method and hardware config. Only the units the method's
// traits ask for exist (method.h): lk has all five per ROP; enderton and
// naive skip the tracker and the sorter; a2c and opaque also skip the
// alpha-reference generator; a blend pass (wboit, total alpha, accumulation)
// has the depth test and the blend unit. Every unit runs one stage of the one
// FunctionalRop, which (with the lines DRAM holds) outlives the pass: a
// multi-pass method elaborates one pipeline per pass (cycle_run.cpp).
//
//   source -> distributor -+-> ordering -> depth test -> [tracker -> sorter] -> [alpha ref] -> writeback
//                          |                          -> blend                                  (blend passes)
//                          +-> ... one chain per ROP unit, each with its ROP cache, all sharing the DRAM
#pragma once
#include <memory>
#include <string>
#include <systemc>
#include <vector>

#include "rtl_models/config/hw_config.h"
#include "rtl_models/core/clock.h"
#include "rtl_models/core/scheduler.h"
#include "rtl_models/core/token.h"
#include "rtl_models/functional/fragment_source.h"
#include "rtl_models/functional/functional_rop.h"
#include "rtl_models/memory/address_map.h"
#include "rtl_models/memory/dram.h"
#include "rtl_models/memory/line_set.h"
#include "rtl_models/memory/rop_cache.h"
#include "rtl_models/observe/interval_log.h"
#include "rtl_models/observe/waveform.h"
#include "rtl_models/units/distributor.h"
#include "rtl_models/units/trace_source.h"

namespace ropsim {

class PixelOrdering;

class RopPipeline : public sc_core::sc_module {
 public:
  /// The pipeline of the rop's current pass (FunctionalRop::begin_pass);
  /// in_dram: the lines DRAM holds, carried from pass to pass.
  RopPipeline(const sc_core::sc_module_name& name, std::unique_ptr<FragmentSource> input, FunctionalRop& rop,
              LineSet& in_dram, const HwConfig& hw);
  ~RopPipeline() override;

  /// Runs to the end of the trace, then flushes the caches; returns the
  /// total cycles. Rethrows an input error (a bad trace record).
  uint64_t run();
  /// Records in wave every unit's activity, every FIFO's occupancy and the
  /// DRAM channels (--vcd); call before run(). Each ROP is one scope (rop0:
  /// its units and the FIFOs they read, in pipeline order); the shared units
  /// (trace_source, distributor with the FIFO it reads) and the DRAM have
  /// their own. `prefix` comes before every scope ("stochastic." for a pass
  /// of a multi-pass method, whose cycles the caller places: Waveform::set_base).
  void trace_to(Waveform& wave, const std::string& prefix = "");

  /// SystemC process activations of the run (the scheduler's).
  uint64_t activations() const { return sched_->activations(); }
  /// Lets the units that can run decoupled (unit.h) do so; call before run().
  void set_decoupled(bool on);
  /// Records the units' activity, the DRAM's bytes and the caches' lookups
  /// in log's rows (--stats-interval); call before run().
  void log_to(IntervalLog* log);

  /// Charges the DRAM's bytes, the caches' misses and the units' cycles to
  /// draws and tiles in attr (attribution.h); call before run().
  void attribute_to(Attribution* attr);

  /// Stores the compressed surfaces through comp and lets the depth test
  /// use its Hi-Z (compression_model.h); call before run().
  void compress_with(CompressionModel* comp);

  FunctionalRop& functional() { return rop_; }
  Retirement& retirement() { return retirement_; }
  const TokenPool& tokens() const { return pool_; }
  /// The most fragments the pipeline can hold at once: its FIFOs' capacities,
  /// the ordering windows and the depth tests' outstanding fragments, and
  /// the source's. The pool holds this many tokens from the start
  /// (memory_estimate.h charges them).
  size_t token_bound() const;
  const Clock& clock() const { return clk_; }
  TraceSource& source() { return *source_; }
  const HwConfig& hw() const { return hw_; }

  struct UnitEntry {
    std::string kind;  ///< "depth_test", ...
    int rop;           ///< -1 for shared units
    Unit* unit;
  };
  const std::vector<UnitEntry>& units() const { return units_; }
  std::vector<TokenFifo*> fifos() const;
  const std::vector<std::unique_ptr<RopCache>>& caches() const { return caches_; }
  const Dram& dram() const { return dram_; }
  uint64_t pipeline_cycles() const { return pipeline_cycles_; }
  uint64_t total_cycles() const { return total_cycles_; }

 private:
  TokenFifo& make_fifo(const std::string& name, uint32_t depth, uint32_t producer_latency);
  template <class U>
  U& add(const std::string& kind, int rop, std::unique_ptr<U> u);

  HwConfig hw_;
  Clock clk_;
  std::unique_ptr<FragmentSource> input_;
  FunctionalRop& rop_;
  TokenPool pool_;
  Retirement retirement_;
  AddressMap amap_;
  Dram dram_;
  LineSet& in_dram_;
  PostedWrites posted_;  // before caches_: they point to it
  std::vector<std::unique_ptr<RopCache>> caches_;
  std::vector<std::unique_ptr<TokenFifo>> fifos_;
  std::unique_ptr<Scheduler> sched_;  // before owned_: the units register with it
  std::vector<std::unique_ptr<Unit>> owned_;
  std::vector<UnitEntry> units_;
  TraceSource* source_ = nullptr;
  uint64_t pipeline_cycles_ = 0, total_cycles_ = 0;
  CompressionModel* comp_ = nullptr;
};

}  // namespace ropsim
