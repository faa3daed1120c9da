#include "rtl_models/units/blend_unit.h"

#include "rtl_models/units/pixel_snapshot.h"

namespace ropsim {

BlendUnit::BlendUnit(const sc_core::sc_module_name& name, const Clock& clk, FunctionalRop& rop, Retirement& retirement,
                     const AddressMap& amap, const HwConfig::Blend& cfg, RopCache& cache, TokenFifo& in)
    : DecoupledUnit(name, clk), rop_(rop), retirement_(retirement), amap_(amap), cfg_(cfg), cache_(cache), in_(in) {}

uint32_t BlendUnit::process(FragToken* t, uint64_t now) {
  const PassKind p = rop_.pass();
  // What the blend replaces in the targets the compressor tracks (pixel_snapshot.h).
  PixelSnapshot trans, accum, depth;
  const bool fb = p == PassKind::kFramebuffer;
  if (CompressionModel* cm = cache_.compression()) {
    if (pass_blends_transmittance(p))
      trans.take(cm, amap_, rop_.setup().bytes, Buffer::kTransmittance, t->f->x, t->f->y, t->px.trans);
    if (pass_blends_accum(p)) accum.take(cm, amap_, rop_.setup().bytes, Buffer::kAccum, t->f->x, t->f->y, t->px.accum);
    if (fb) depth.take(cm, amap_, rop_.setup().bytes, Buffer::kDepth, t->f->x, t->f->y, t->px.depth, t->px.plane);
  }
  const uint32_t n = run_stage(rop_.blend(), *t);
  const Owner o = t->owner();
  blended_ += n;
  if (pass_blends_transmittance(p))
    amap_.for_each_sample_line(Buffer::kTransmittance, t->f->x, t->f->y, t->survivors, [&](uint64_t line) {
      cache_.post_write(line, Buffer::kTransmittance, now, o, trans.patch(line));
    });
  if (pass_blends_accum(p))
    amap_.for_each_sample_line(Buffer::kAccum, t->f->x, t->f->y, t->survivors, [&](uint64_t line) {
      cache_.post_write(line, Buffer::kAccum, now, o, accum.patch(line));
    });
  // blend: the depth of the samples its draw writes.
  if (fb)
    amap_.for_each_sample_line(Buffer::kDepth, t->f->x, t->f->y, t->depth_written, [&](uint64_t line) {
      cache_.post_write(line, Buffer::kDepth, now, o, depth.patch(line));
    });
  return n;
}

void BlendUnit::advance(uint64_t limit) {
  for (;;) {
    if (in_.empty()) {
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
    took(tok->tile, t);
    ++stats_.fragments;
    const uint32_t n = process(tok, t);
    stats_.samples += n;
    busy_until_ = t + std::max<uint32_t>(1, ceil_div(n, cfg_.samples_per_clock));
    retirement_.retire(tok, t + cfg_.latency_cycles);
    set_busy(t, busy_until_, Activity::kStarved);
  }
}

}  // namespace ropsim
