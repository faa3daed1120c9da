#include "depth_test.h"

#include "depth.h"
#include "method_kernels.h"

namespace ropsim {

DepthTest::DepthTest(const sc_core::sc_module_name& name, const Clock& clk, RopContext& ctx,
                     const HwConfig::DepthTest& cfg, RopCache& cache, TokenFifo& in, TokenFifo& out)
    : Unit(name, clk), ctx_(ctx), cfg_(cfg), cache_(cache), in_(in), out_(out) {}

uint64_t DepthTest::evaluate(FragToken* t, uint64_t now) {
  const Fragment& f = t->f;
  Counters& c = ctx_.counters;
  const Method method = ctx_.golden.method;
  const int covered_count = __builtin_popcountll(f.coverage);
  ++c.fragments;
  c.samples_tested += covered_count;
  c.depth_bytes_read += 4u * covered_count;
  t->covered = f.coverage;
  if (method == Method::kA2c) {
    const uint32_t k = a2c_sample_count(ctx_.fixed_alpha(f.alpha), ctx_.golden.numerics.alpha_bits,
                                        ctx_.header.spp, f.x, f.y);
    t->covered &= ctx_.a2c_prefix[k];
    c.samples_opacity_passed += __builtin_popcountll(t->covered);
  }
  uint64_t s = 0;
  if (ctx_.header.depth_mode == DepthMode::kPlane) {
    for (uint64_t m = t->covered; m; m &= m - 1) {
      const int i = __builtin_ctzll(m);
      t->z[i] = plane_depth(f.z0, f.dzdx, f.dzdy, ctx_.offset_x[size_t(i)], ctx_.offset_y[size_t(i)]);
      s |= uint64_t{depth_passes(t->z[i], t->px.depth[i])} << i;
    }
  } else {
    fragment_sample_depths(ctx_.header, f, t->z);
    for (uint64_t m = t->covered; m; m &= m - 1) {
      const int i = __builtin_ctzll(m);
      s |= uint64_t{depth_passes(t->z[i], t->px.depth[i])} << i;
    }
  }
  t->survivors = s;
  t->m = uint32_t(__builtin_popcountll(s));
  stats_.samples += uint64_t(__builtin_popcountll(t->covered));
  if (method == Method::kLk || method == Method::kEnderton || method == Method::kNaive)
    c.samples_depth_passed += t->m;
  if (method == Method::kLk) c.tracker_bytes_read += uint64_t(ctx_.tracker_bytes);
  // Load the pixel's state: the depth lines of the tested samples, and the tracker.
  uint64_t ready = now;
  ctx_.amap.for_each_sample_line(Buffer::kDepth, f.x, f.y, t->covered,
                                 [&](uint64_t line) { ready = std::max(ready, cache_.read(line, Buffer::kDepth, now)); });
  if (method == Method::kLk)
    ctx_.amap.for_each_tracker_line(
        f.x, f.y, [&](uint64_t line) { ready = std::max(ready, cache_.read(line, Buffer::kTracker, now)); });
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
      ctx_.retire(t, now);
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
      seen_ = true;
      ++stats_.fragments;
      const uint64_t ready = evaluate(t, now);
      pending_.push(Pending{std::max(ready, now), t->seq, t, t->survivors == 0});
      busy_until_ = now + std::max<uint32_t>(1, ceil_div(uint32_t(__builtin_popcountll(t->covered)), cfg_.samples_per_clock));
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
  return {{"killed", double(killed_), "fragments with no surviving sample, retired here"}};
}

}  // namespace ropsim
