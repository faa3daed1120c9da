#include "rtl_models/units/depth_test.h"

#include <algorithm>
#include <cstring>
#include <string>

#include "rtl_models/functional/framebuffer_blend.h"
#include "rtl_models/units/blend_unit.h"
#include "util/errors.h"

namespace ropsim {

DepthTest::DepthTest(const sc_core::sc_module_name& name, const Clock& clk, FunctionalRop& rop, Retirement& retirement,
                     const AddressMap& amap, const HwConfig::DepthTest& cfg, RopCache& cache, TokenFifo& in,
                     TokenFifo& out)
    : Unit(name, clk), rop_(rop), retirement_(retirement), amap_(amap), cfg_(cfg), cache_(cache), in_(in), out_(out) {}

namespace {

/// The nearest of the tested samples' depths (mask covered) and 1, as
/// std::min folds them: for a fully covered pixel whose depths are none
/// negative or NaN (bit patterns at most +inf's), through the bit patterns,
/// which order as the depths do (one vectorised pass).
float nearest_tested(const float* z, uint64_t covered, uint32_t spp) {
  if (covered == (spp == 64 ? ~uint64_t{0} : (uint64_t{1} << spp) - 1)) {
    uint32_t lo = ~0u, hi = 0;
    for (uint32_t i = 0; i < spp; ++i) {
      uint32_t bits;
      std::memcpy(&bits, &z[i], 4);
      lo = std::min(lo, bits);
      hi = std::max(hi, bits);
    }
    if (hi <= 0x7F800000u) {
      float m;
      std::memcpy(&m, &lo, 4);
      return std::min(1.0f, m);
    }
  }
  float zmin = 1.0f;
  for (uint64_t m = covered; m; m &= m - 1) zmin = std::min(zmin, z[__builtin_ctzll(m)]);
  return zmin;
}

}  // namespace

uint64_t DepthTest::evaluate(FragToken* t, uint64_t now) {
  stats_.samples += run_stage(rop_.depth(), *t);
  // Load the pixel's state: the depth lines of the tested samples, and the tracker.
  uint64_t ready = now;
  const Owner o = t->owner();
  if (rop_.setup().cfg.method == Method::kSlab && t->route == DrawRoute::kMethod) {
    // slab: the pixel's layers, no per-sample depth (over a pre-pass's
    // background: and the covered samples' depth, which its layers test).
    amap_.for_each_layer_line(
        t->f->x, t->f->y, [&](uint64_t line) { ready = std::max(ready, cache_.read(line, Buffer::kLayers, now, o)); });
    if (rop_.setup().prepass && t->draw->depth_test)
      amap_.for_each_sample_line(Buffer::kDepth, t->f->x, t->f->y, t->f->coverage, [&](uint64_t line) {
        ready = std::max(ready, cache_.read(line, Buffer::kDepth, now, o));
      });
    return ready;
  }
  // Hierarchical Z: a fragment whose tested samples all lie beyond its
  // tile's farthest stored depth fails them all; it reads nothing and
  // retires here (compression_model.h gives the update rule). Only for the
  // methods' own test and for draws testing LESS or LEQUAL (blend's draws and
  // the opaque and blended draws of a frame test with their own functions).
  // (A src-over draw with its depth test off passes every sample: no Hi-Z.)
  const bool own_test = rop_.setup().cfg.method == Method::kBlend || t->route != DrawRoute::kMethod;
  const bool hiz_applies = !own_test ? !t->draw || t->draw->depth_test
                                     : t->draw->depth_test && (t->draw->depth_func == DepthFunc::kLess ||
                                                               t->draw->depth_func == DepthFunc::kLequal);
  if (CompressionModel* cm = cache_.compression(); cm && cm->hiz() && t->covered && hiz_applies) {
    if (cm->hiz_rejects(t->f->x, t->f->y, nearest_tested(t->z, t->covered, uint32_t(rop_.setup().spp)))) {
      if (t->survivors)
        throw InternalError("Hi-Z never rejects a fragment that passes: pixel (" + std::to_string(t->f->x) + ", " +
                            std::to_string(t->f->y) + ") had surviving samples");
      uint64_t lines = 0;
      amap_.for_each_sample_line(Buffer::kDepth, t->f->x, t->f->y, t->covered, [&](uint64_t) { ++lines; });
      cm->count_skipped(lines);
      return ready;
    }
  }
  amap_.for_each_sample_line(Buffer::kDepth, t->f->x, t->f->y, t->covered, [&](uint64_t line) {
    ready = std::max(ready, cache_.read(line, Buffer::kDepth, now, o));
  });
  if (rop_.pass_uses_tracker() && t->route == DrawRoute::kMethod)
    amap_.for_each_tracker_line(
        t->f->x, t->f->y, [&](uint64_t line) { ready = std::max(ready, cache_.read(line, Buffer::kTracker, now, o)); });
  // Blend passes: the destination of the blend (read-modify-write), the
  // render-target lines of the surviving samples, fetched with the depth.
  // (blend: not for a draw that replaces every channel, which reads none.)
  const PassKind p = rop_.pass();
  const bool fb_read = p != PassKind::kFramebuffer || draw_reads_colour(*t->draw);
  for (Buffer b : {Buffer::kTransmittance, Buffer::kAccum})
    if (b == Buffer::kTransmittance ? pass_blends_transmittance(p) : pass_blends_accum(p) && fb_read)
      amap_.for_each_sample_line(b, t->f->x, t->f->y, t->survivors,
                                 [&](uint64_t line) { ready = std::max(ready, cache_.read(line, b, now, o)); });
  // An additive or other blended draw of a frame: the colour it blends into.
  if (t->route != DrawRoute::kMethod && draw_reads_colour(*t->draw))
    amap_.for_each_sample_line(Buffer::kColor, t->f->x, t->f->y, t->survivors, [&](uint64_t line) {
      ready = std::max(ready, cache_.read(line, Buffer::kColor, now, o));
    });
  return ready;
}

void DepthTest::step(uint64_t now) {
  // 1. One fragment whose data has arrived leaves (killed ones just retire).
  bool emitted = false, blocked = false;
  while (!pending_.empty() && pending_.front().ready <= now) {
    FragToken* t = pending_.front().t;
    if (pending_.front().killed) {
      pending_.pop_front();
      ++killed_;
      retirement_.retire(t, now);
      continue;
    }
    if (emitted) break;
    if (!out_.can_push(now)) {
      blocked = true;
      out_.wait_for_space(now);
      break;
    }
    pending_.pop_front();
    out_.push(t, now, now + cfg_.latency_cycles);
    emitted = true;
  }
  // 2. Accept a fragment and start loading its pixel.
  bool accepted = false, full = false;
  if (now >= busy_until_ && in_.can_pop(now)) {
    if (pending_.size() >= cfg_.max_outstanding) {
      full = true;
    } else {
      FragToken* t = in_.pop(now);
      took(t->tile, now);
      seen_ = true;
      ++stats_.fragments;
      const uint64_t ready = evaluate(t, now);
      pending_.push(Pending{std::max(ready, now), t->seq, t, t->survivors == 0});
      busy_until_ =
          now + std::max<uint32_t>(1, ceil_div(uint32_t(__builtin_popcountll(t->covered)), cfg_.samples_per_clock));
      accepted = true;
    }
  }
  // 3. What the unit did this cycle.
  if (accepted) {
    set_busy(now, busy_until_, pending_.empty() ? Activity::kStarved : Activity::kMemory);
  } else if (blocked) {
    set_activity(Activity::kBlocked, now);
  } else if (full || !pending_.empty()) {
    set_activity(Activity::kMemory, now);
  } else if (!in_.occupied(now) && in_.closed_by(now)) {
    if (!out_.closed()) out_.close(now);
    set_activity(Activity::kIdle, now);
  } else {
    set_activity(seen_ || in_.occupied(now) ? Activity::kStarved : Activity::kIdle, now);
  }
  // 4. The next cycle anything can happen (pushes into in_ also wake the unit).
  if (!pending_.empty() && !blocked) wake_at(std::max(now + (emitted ? 1 : 0), pending_.front().ready));
  if (!in_.empty() && !full) wake_at(std::max({busy_until_, in_.head_visible(), now + 1}));
  if (emitted && !in_.empty() && full) wake_at(now + 1);
}

std::vector<Unit::Extra> DepthTest::extras() const {
  std::vector<Extra> e = {{"killed", double(killed_), "fragments", "fragments with no surviving sample, retired here"}};
  const Method m = rop_.setup().cfg.method;
  if (m == Method::kHashed || m == Method::kHashedA2c || m == Method::kSlab)
    e.push_back({"selection_hashes", double(rop_.depth().selection_hashes()), "hashes",
                 "hashed, hashed-a2c, slab: random numbers the coverage selection hashed (1 or 3 per fragment; "
                 "slab: R + 1), pipelined beside the depth read"});
  return e;
}

}  // namespace ropsim
