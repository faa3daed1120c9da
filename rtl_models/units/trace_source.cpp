#include "rtl_models/units/trace_source.h"

namespace ropsim {

TraceSource::TraceSource(const sc_core::sc_module_name& name, const Clock& clk, FragmentSource& input,
                         FunctionalRop& rop, TokenPool& pool, const HwConfig::Source& cfg, TokenFifo& out,
                         const RopOwnership& tiles)
    : DecoupledUnit(name, clk), input_(input), rop_(rop), pool_(pool), cfg_(cfg), out_(out), tiles_(tiles) {}

void TraceSource::advance(uint64_t limit) {
  while (!done_) {
    const uint64_t t = t_;
    if (t > limit) return wake_at(t);
    // Up to fragments_per_clock fragments at clock t, while the FIFO has slots.
    while (n_ < cfg_.fragments_per_clock && !done_) {
      if (!out_.can_push(t)) {
        // Decoupled, a slot the distributor has not yet freed may still free
        // before t: the clock resumes here when it pops.
        if (limit == kForever && out_.space_from() == TokenFifo::kUndecided) return out_.notify_on_pop();
        break;
      }
      FragToken* tok = pool_.get();
      bool got = false;
      try {
        got = input_.next(tok->fragment);
        // The pixel's state, found (its tile allocated, and charged to the
        // memory budget, which may refuse it) here and fetched into the
        // host's caches while the fragment waits in the FIFOs: the depth
        // test reads it many fragments later. Host speed only; no model effect.
        if (got) {
          // A counting token starts empty; the tile the fetch allocates is
          // its fragment's (tiles_touched).
          tok->counting = counting_;
          const uint64_t tiles = rop_.store().tiles();
          rop_.fetch(*tok);
          if (counting_) {
            tok->counts = Counters{};
            tok->counts.tiles_touched = rop_.store().tiles() - tiles;
          }
        }
      } catch (...) {
        error_ = std::current_exception();
        got = false;
      }
      if (!got) {
        pool_.put(tok);
        done_ = true;
        out_.close(t);
        if (error_) sc_core::sc_stop();
        break;
      }
      tok->seq = seq_++;
      tok->pixel_key = uint64_t(tok->fragment.y) * rop_.header().width + tok->fragment.x;
      if (attributing()) {  // the units' tile maps (attribution.h)
        tok->tile = tiles_.tile_of(tok->fragment.x, tok->fragment.y);
        took(tok->tile, t);
      }
      const int spp = rop_.header().spp;
      __builtin_prefetch(tok->px.depth);
      __builtin_prefetch(tok->px.depth + spp - 1);
      __builtin_prefetch(tok->px.rgb);
      __builtin_prefetch(tok->px.rgb + 3 * spp - 1);
      if (tok->px.tracker) __builtin_prefetch(tok->px.tracker);
      out_.push(tok, t, t + 1);
      ++n_;
      ++stats_.fragments;
      if (on_progress && seq_ % kProgressEvery == 0) on_progress(seq_, input_.consumed());
    }
    // Clock t is decided.
    if (!done_) out_.settle(t + 1);  // later pushes are at t + 1 or after, visible after t + 1
    if (n_) {
      set_activity(Activity::kBusy, t);
      if (done_) set_activity(Activity::kIdle, t + 1);
      n_ = 0;
      t_ = t + 1;
      continue;
    }
    if (done_) {
      set_activity(Activity::kIdle, t);
      return;
    }
    // No slot at t.
    set_activity(Activity::kBlocked, t);
    const uint64_t s = out_.space_from();
    if (s == TokenFifo::kUndecided) return out_.wait_for_space(t);
    t_ = s;
  }
}

}  // namespace ropsim
