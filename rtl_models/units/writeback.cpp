#include "rtl_models/units/writeback.h"

#include "rtl_models/units/pixel_snapshot.h"

namespace ropsim {

Writeback::Writeback(const sc_core::sc_module_name& name, const Clock& clk, FunctionalRop& rop, Retirement& retirement,
                     const AddressMap& amap, const HwConfig::Writeback& cfg, RopCache& cache, TokenFifo& in)
    : DecoupledUnit(name, clk), rop_(rop), retirement_(retirement), amap_(amap), cfg_(cfg), cache_(cache), in_(in) {}

uint32_t Writeback::process(FragToken* t, uint64_t now) {
  // What the write replaces in the surfaces the compressor tracks (pixel_snapshot.h).
  // Depth-based methods store depth only; a frame's opaque and blended draws write colour.
  // Over a pre-pass, +ac's colour goes to the accumulation target and +depth
  // marks the transmittance target (method.h).
  const Method m = rop_.setup().cfg.method;
  const bool own = t->route == DrawRoute::kMethod, prepass = rop_.setup().prepass;
  const bool color = stochastic_writes_colour_buffer(m, prepass) || !own;
  const bool accum = own && stochastic_colour_in_accum(m, prepass);
  const bool mark = own && stochastic_marks_transmittance(m, prepass);
  PixelSnapshot depth, rgb, target;
  if (CompressionModel* cm = cache_.compression()) {
    depth.take(cm, amap_, rop_.setup().bytes, Buffer::kDepth, t->f->x, t->f->y, t->px.depth, t->px.plane);
    if (color) rgb.take(cm, amap_, rop_.setup().bytes, Buffer::kColor, t->f->x, t->f->y, t->px.rgb);
    if (accum) target.take(cm, amap_, rop_.setup().bytes, Buffer::kAccum, t->f->x, t->f->y, t->px.accum);
    if (mark) target.take(cm, amap_, rop_.setup().bytes, Buffer::kTransmittance, t->f->x, t->f->y, t->px.trans);
  }
  const uint32_t examined = run_stage(rop_.write(), *t);
  const Owner o = t->owner();
  written_ += uint64_t(__builtin_popcountll(t->written));
  amap_.for_each_sample_line(Buffer::kDepth, t->f->x, t->f->y, t->depth_written, [&](uint64_t line) {
    cache_.post_write(line, Buffer::kDepth, now, o, depth.patch(line));
  });
  if (color)
    amap_.for_each_sample_line(Buffer::kColor, t->f->x, t->f->y, t->written, [&](uint64_t line) {
      cache_.post_write(line, Buffer::kColor, now, o, rgb.patch(line));
    });
  if (accum || mark) {
    const Buffer b = accum ? Buffer::kAccum : Buffer::kTransmittance;
    amap_.for_each_sample_line(b, t->f->x, t->f->y, t->written,
                               [&](uint64_t line) { cache_.post_write(line, b, now, o, target.patch(line)); });
  }
  // lk: the tracker's updated state (written whatever the opacity test said).
  if (rop_.pass_uses_tracker() && t->route == DrawRoute::kMethod)
    amap_.for_each_tracker_line(t->f->x, t->f->y,
                                [&](uint64_t line) { cache_.post_write(line, Buffer::kTracker, now, o); });
  // slab: the pixel's layers, rewritten when the fragment was inserted.
  if (m == Method::kSlab && t->slab.kept)
    amap_.for_each_layer_line(t->f->x, t->f->y,
                              [&](uint64_t line) { cache_.post_write(line, Buffer::kLayers, now, o); });
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
    took(tok->tile, t);
    ++stats_.fragments;
    const uint32_t examined = process(tok, t);
    stats_.samples += examined;
    busy_until_ = t + std::max<uint32_t>(1, ceil_div(examined, cfg_.samples_per_clock));
    retirement_.retire(tok, t + cfg_.latency_cycles);
    set_busy(t, busy_until_, Activity::kStarved);
  }
}

}  // namespace ropsim
