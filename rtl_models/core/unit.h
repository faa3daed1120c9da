// Base of every SystemC unit: an sc_module run by its clock's Scheduler
// (scheduler.h) at the cycles it asks for, never by a free-running clock;
// activity accounting without per-cycle work (the time between two
// activations is charged to the activity recorded at the first).
//
// Temporal decoupling. A unit whose function touches no timed shared state
// (no cache or DRAM access, no scoreboard) computes the same outputs at the
// same cycles whether it runs at each cycle or ahead of SystemC time, as long
// as everything it decides on is already decided: the entries in its input
// FIFO (with their visible cycles) and the slots of its output FIFO (with the
// cycles they were freed). Such a unit, when decoupled, does all the work its
// FIFOs allow the moment a FIFO changes (on_input, on_space, on_close), with
// no SystemC activation, like a TLM-2.0 loosely-timed initiator that never
// needs to synchronise. Units that access memory stay in lockstep with
// SystemC time, so the cache and DRAM see requests in cycle order. Lockstep
// and decoupled runs give identical results (tests/test_cycle_determinism.cpp).
#pragma once
#include <algorithm>
#include <array>
#include <cstdint>
#include <string>
#include <systemc>
#include <vector>

#include "rtl_models/core/clock.h"
#include "rtl_models/core/scheduler.h"
#include "rtl_models/observe/attribution.h"
#include "rtl_models/observe/interval_log.h"
#include "rtl_models/observe/waveform.h"

namespace ropsim {

/// What a unit does in a cycle. Every cycle of the run is charged to one.
enum class Activity : int {
  kIdle,     ///< no work: before its first fragment or after its input closed
  kBusy,     ///< processing (a fragment's initiation interval)
  kStarved,  ///< waiting for input while upstream still works
  kBlocked,  ///< output FIFO full
  kHazard,   ///< pixel ordering: every waiting fragment's pixel is in flight, or the scoreboard is full
  kMemory,   ///< waiting for the ROP cache / DRAM
};
constexpr int kActivities = 6;
static_assert(kActivities == kIntervalActivities, "interval_log.h counts the same activities");
const char* to_string(Activity a);

struct UnitStats {
  std::array<uint64_t, kActivities> cycles{};  ///< cycles per Activity
  uint64_t fragments = 0;                      ///< fragments accepted
  uint64_t samples = 0;                        ///< samples processed (unit-specific: tested, sorted, hashed, written)
  uint64_t activations = 0;                    ///< times the scheduler ran the unit (host cost)
};

class Unit : public sc_core::sc_module {
 public:
  /// Registers with the clock's scheduler, which must exist.
  Unit(const sc_core::sc_module_name& name, const Clock& clk);

  /// Runs the unit at the given cycle (now or later). Every request is kept
  /// until its cycle has come; repeated requests for one cycle run it once.
  void wake_at(uint64_t cycle) {
    if (cycle == last_request_) return;
    last_request_ = cycle;
    sched_.request(index_, cycle);
  }
  /// The scheduler runs the unit at cycle now.
  void activate(uint64_t now) {
    ++stats_.activations;
    last_request_ = ~uint64_t{0};
    step(now);
  }
  /// A FIFO the unit reads got an entry, visible from cycle `visible`.
  virtual void on_input(uint64_t visible) { wake_at(visible); }
  /// The output FIFO the unit waits on has a free slot from `cycle`.
  virtual void on_space(uint64_t cycle) { wake_at(cycle); }
  /// A FIFO the unit reads was closed; the unit may notice from `cycle`.
  virtual void on_close(uint64_t cycle) { wake_at(cycle); }
  /// A decoupled producer declared more of its input settled (TimedFifo::settle).
  virtual void on_settle() {}
  /// Lets a unit that supports it run ahead of SystemC time (see above).
  void set_decoupled(bool on) { decoupled_ = on; }
  /// Charges the cycles up to end to the current activity (end of the run).
  void close_accounting(uint64_t end) { set_activity(Activity::kIdle, end); }
  /// Also charges every span of cycles to log's rows, as unit kind `kind`
  /// (--stats-interval); before the run.
  void log_to(IntervalLog* log, int kind) {
    log_ = log;
    log_kind_ = kind;
  }
  const UnitStats& stats() const { return stats_; }
  /// Unit-specific figures for the report: name, value, unit.
  /// A unit-specific statistic: its name, value, unit and one-line meaning.
  struct Extra {
    std::string name;
    double value;
    std::string unit;
    std::string meaning;
  };
  virtual std::vector<Extra> extras() const { return {}; }
  /// Also charges every span of cycles to a tile in attr (attribution.h:
  /// the tile of the fragment it took last, took()); before the run.
  void attribute_to(Attribution* attr) { attr_ = attr; }
  bool attributing() const { return attr_ != nullptr; }
  /// The unit takes a fragment of tile `tile` at cycle t: its cycles from t
  /// on are that tile's (those before its first fragment too).
  void took(uint32_t tile, uint64_t t) {
    if (__builtin_expect(attr_ != nullptr, 0)) took_tile(tile, t);
  }
  /// Ends the attribution: a unit that took no fragment charges its cycles
  /// to no tile (after close_accounting).
  void close_attribution();
  /// Also records every span of cycles in `wave`'s state signal `sig`, whose
  /// states are the Activity names (--vcd); before the run.
  void trace_to(Waveform* wave, int sig) {
    wave_ = wave;
    wave_sig_ = sig;
  }

 protected:
  /// One activation at cycle now: move fragments, set the activity, and arm
  /// the next wake-up (or rely on a FIFO to wake the unit).
  virtual void step(uint64_t now) = 0;
  /// From cycle t the unit does a (inside a busy interval: after it).
  void set_activity(Activity a, uint64_t t) {
    charge_to(t);
    if (t < busy_end_)
      after_ = a;
    else
      act_ = a;
  }
  /// Busy for [t, until), then `after` until the next change, so a unit need
  /// not wake at the end of its initiation interval just to account for it.
  void set_busy(uint64_t t, uint64_t until, Activity after) {
    charge_to(t);
    act_ = Activity::kBusy;
    busy_end_ = until;
    after_ = after;
  }
  const Clock& clk_;
  UnitStats stats_;
  bool decoupled_ = false;

 private:
  void charge_to(uint64_t t) {
    if (t <= since_) return;
    if (busy_end_ > since_) {
      const uint64_t e = std::min(busy_end_, t);
      stats_.cycles[size_t(Activity::kBusy)] += e - since_;
      if (log_) log_->add_activity(log_kind_, int(Activity::kBusy), since_, e);
      if (wave_) wave_->set(wave_sig_, since_, uint64_t(Activity::kBusy));
      since_ = e;
      if (since_ == busy_end_) act_ = after_;
    }
    if (t > since_) {
      stats_.cycles[size_t(act_)] += t - since_;
      if (log_) log_->add_activity(log_kind_, int(act_), since_, t);
      if (wave_) wave_->set(wave_sig_, since_, uint64_t(act_));
      since_ = t;
    }
  }
  // The tile attribution (attribution.h) adds nothing to the accounting
  // above: at each switch of tile it charges the cycles accounted since the
  // previous switch (stats_.cycles now minus then) to the tile it leaves.
  void took_tile(uint32_t tile, uint64_t t);
  void charge_tile(bool owned);
  Attribution* attr_ = nullptr;
  bool has_tile_ = false;
  uint32_t tile_ = 0;
  std::array<uint64_t, kActivities> charged_{};  // stats_.cycles at the last switch
  IntervalLog* log_ = nullptr;
  int log_kind_ = -1;
  Waveform* wave_ = nullptr;
  int wave_sig_ = -1;
  Scheduler& sched_;
  uint32_t index_;
  uint64_t last_request_ = ~uint64_t{0};
  Activity act_ = Activity::kIdle, after_ = Activity::kIdle;
  uint64_t since_ = 0, busy_end_ = 0;
};

/// A unit that can run decoupled: its behaviour is advance(limit), which does
/// everything decided up to cycle `limit` (SystemC's current cycle in lockstep,
/// kForever when decoupled) and arms a wake-up for what it could not do yet.
/// The FIFO hooks record what they tell and, when decoupled, advance at once.
class DecoupledUnit : public Unit {
 public:
  static constexpr uint64_t kForever = ~uint64_t{0};
  using Unit::Unit;
  void on_input(uint64_t visible) override { decoupled_ ? run_ahead() : wake_at(visible); }
  void on_space(uint64_t cycle) override { decoupled_ ? run_ahead() : wake_at(cycle); }
  void on_close(uint64_t cycle) override {
    close_seen_ = cycle;
    decoupled_ ? run_ahead() : wake_at(cycle);
  }
  void on_settle() override {
    if (decoupled_) run_ahead();
  }

 protected:
  virtual void advance(uint64_t limit) = 0;
  void step(uint64_t now) override { decoupled_ ? run_ahead() : advance(now); }
  /// Advances to kForever; a hook that fires inside (a pop that frees the
  /// upstream unit, which pushes again) makes the loop run once more.
  void run_ahead() {
    if (advancing_) {
      again_ = true;
      return;
    }
    advancing_ = true;
    do {
      again_ = false;
      advance(kForever);
    } while (again_);
    advancing_ = false;
  }
  uint64_t close_seen_ = 0;  ///< the input's close is seen from this cycle (on_close)

 private:
  bool advancing_ = false, again_ = false;
};

}  // namespace ropsim
