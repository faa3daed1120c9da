#include "trace_source.h"

namespace ropsim {

TraceSource::TraceSource(const sc_core::sc_module_name& name, const Clock& clk, RopContext& ctx,
                         const HwConfig::Source& cfg, Supplier supplier, TokenFifo& out)
    : Unit(name, clk), ctx_(ctx), cfg_(cfg), supplier_(std::move(supplier)), out_(out) {}

void TraceSource::step(uint64_t now) {
  if (done_) {
    set_activity(Activity::kIdle, now);
    return;
  }
  if (now < busy_until_) {
    wake_at(busy_until_);
    return;
  }
  uint32_t n = 0;
  bool blocked = false;
  while (n < cfg_.fragments_per_clock) {
    if (!out_.can_push(now)) {
      blocked = true;
      break;
    }
    FragToken* t = ctx_.pool.get();
    bool got = false;
    try {
      got = supplier_(t->f);
    } catch (...) {
      error_ = std::current_exception();
      got = false;
    }
    if (!got) {
      ctx_.pool.put(t);
      done_ = true;
      out_.close(now);
      if (error_) sc_core::sc_stop();
      break;
    }
    t->seq = seq_++;
    t->pixel_key = uint64_t(t->f.y) * ctx_.header.width + t->f.x;
    out_.push(t, now, now + 1);
    ++n;
    if (on_progress && seq_ % kProgressEvery == 0) on_progress(seq_);
  }
  stats_.fragments += n;
  if (n) {
    busy_until_ = now + 1;
    set_activity(Activity::kBusy, now);
    wake_at(now + 1);
  } else if (blocked) {
    set_activity(Activity::kBlocked, now);
    out_.wait_for_space(now);
  } else {
    set_activity(Activity::kIdle, now);
  }
  if (blocked && n) out_.wait_for_space(now);
}

}  // namespace ropsim
