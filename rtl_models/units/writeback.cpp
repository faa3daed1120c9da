#include "writeback.h"

#include "opacity.h"

namespace ropsim {

Writeback::Writeback(const sc_core::sc_module_name& name, const Clock& clk, RopContext& ctx,
                     const HwConfig::Writeback& cfg, RopCache& cache, TokenFifo& in)
    : DecoupledUnit(name, clk), ctx_(ctx), cfg_(cfg), cache_(cache), in_(in) {}

uint32_t Writeback::process(FragToken* t, uint64_t now) {
  const Numerics& num = ctx_.golden.numerics;
  const uint16_t* rgb16 = ctx_.half_color(t->f.rgb);
  Counters& c = ctx_.counters;
  uint64_t wrote = 0;
  uint32_t examined = t->m;
  switch (ctx_.golden.method) {
    case Method::kLk: {
      const uint64_t a = ctx_.fixed_alpha(t->f.alpha);
      for (uint32_t j = 0; j < t->m; ++j)
        if (opacity_passes(a, num.alpha_bits, t->ref[j], num.hash_bits)) wrote |= uint64_t{1} << t->order[j];
      c.samples_opacity_passed += uint64_t(__builtin_popcountll(wrote));
      break;
    }
    case Method::kEnderton:
      for (uint32_t j = 0; j < t->count; ++j) wrote |= uint64_t{1} << t->list[j];
      c.samples_opacity_passed += t->count;
      examined = t->count;
      break;
    case Method::kNaive: {
      const uint64_t a = ctx_.fixed_alpha(t->f.alpha);
      for (uint64_t s = t->survivors; s; s &= s - 1) {
        const int i = __builtin_ctzll(s);
        if (opacity_passes(a, num.alpha_bits, t->ref[i], 32)) wrote |= uint64_t{1} << i;
      }
      c.samples_opacity_passed += uint64_t(__builtin_popcountll(wrote));
      break;
    }
    case Method::kA2c:
      wrote = t->survivors;
      c.samples_depth_passed += t->m;
      break;
    case Method::kOpaque:
      wrote = t->survivors;
      c.samples_depth_passed += t->m;
      c.samples_opacity_passed += t->m;
      break;
    case Method::kReference: break;
  }
  const uint32_t n = uint32_t(__builtin_popcountll(wrote));
  for (uint64_t s = wrote; s; s &= s - 1) {
    const int i = __builtin_ctzll(s);
    t->px.write_sample(i, t->z[i], rgb16);
  }
  c.samples_written += n;
  c.depth_bytes_written += 4u * n;
  c.color_bytes_written += 6u * n;
  written_ += n;
  ctx_.amap.for_each_sample_line(Buffer::kDepth, t->f.x, t->f.y, wrote,
                                 [&](uint64_t line) { cache_.post_write(line, Buffer::kDepth, now); });
  ctx_.amap.for_each_sample_line(Buffer::kColor, t->f.x, t->f.y, wrote,
                                 [&](uint64_t line) { cache_.post_write(line, Buffer::kColor, now); });
  // lk: the tracker's updated state (written whatever the opacity test said).
  if (ctx_.golden.method == Method::kLk)
    ctx_.amap.for_each_tracker_line(t->f.x, t->f.y, [&](uint64_t line) { cache_.post_write(line, Buffer::kTracker, now); });
  return examined;
}

void Writeback::advance(uint64_t limit) {
  for (;;) {
    if (in_.empty()) {
      // Everything is through; after the input closes the unit is idle.
      if (in_.closed() && !closed_) {
        const uint64_t t = std::max(close_seen_, busy_until_);
        if (t > limit) return wake_at(t);
        closed_ = true;
        set_activity(Activity::kIdle, t);
      }
      return;  // a push or a close comes back here
    }
    const uint64_t t = std::max(busy_until_, in_.head_visible());
    if (t > limit) return wake_at(t);
    FragToken* tok = in_.pop(t);
    ++stats_.fragments;
    const uint32_t examined = process(tok, t);
    stats_.samples += examined;
    busy_until_ = t + std::max<uint32_t>(1, ceil_div(examined, cfg_.samples_per_clock));
    ctx_.retire(tok, t + cfg_.latency_cycles);
    set_busy(t, busy_until_, Activity::kStarved);
  }
}

}  // namespace ropsim
