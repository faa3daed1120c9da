#include "traces/format/frame_stats.h"

#include <algorithm>

namespace ropsim {

FrameStatsCounter::FrameStatsCounter(const TraceHeader& h)
    : table_(h.draws), default_kind_(draw_kind(default_draw_state(0))), see_through_(h.width, h.height) {
  for (const DrawState& d : table_.states()) kind_of_.push_back(draw_kind(d));
  s_.screen_samples = uint64_t(h.width) * h.height * uint64_t(h.spp);
}

void FrameStatsCounter::add(const Fragment& f) {
  const uint64_t c = uint64_t(__builtin_popcountll(f.coverage));
  ++s_.fragments;
  s_.covered += c;
  max_draw_ = std::max(max_draw_, f.draw_id);
  const DrawKind k = table_.empty() ? default_kind_ : kind_of_[size_t(table_.find(f.draw_id) - table_.states().data())];
  ++s_.kind_fragments[size_t(k)];
  s_.kind_covered[size_t(k)] += c;
  if (!is_transparent_kind(k)) return;
  Transparent& t = see_through_.get(f.x, f.y, [](uint32_t, uint32_t) { return std::make_unique<Transparent>(); });
  const size_t i = (f.y & 7u) * 8 + (f.x & 7u);
  ++t.n[i];
  t.covered[i] |= f.coverage;
  s_.transparent_covered += c;
  if (f.alpha < 1.0f) {
    ++s_.translucent_fragments;
    s_.translucent_covered += c;
  }
}

FrameStats FrameStatsCounter::finish() const {
  FrameStats s = s_;
  if (table_.empty())
    s.kind_draws[size_t(default_kind_)] = s.fragments ? uint64_t(max_draw_) + 1 : 0;
  else
    for (DrawKind k : kind_of_) ++s.kind_draws[size_t(k)];
  see_through_.for_each([&](uint32_t, uint32_t, const Transparent& t) {
    for (size_t i = 0; i < 64; ++i) {
      if (!t.n[i]) continue;
      ++s.transparent_pixels;
      s.transparent_fragments += t.n[i];
      s.transparent_max = std::max<uint64_t>(s.transparent_max, t.n[i]);
      s.transparent_samples += uint64_t(__builtin_popcountll(t.covered[i]));
    }
  });
  return s;
}

FrameStats frame_stats_of(const std::string& trace_path) {
  TraceReader r(trace_path);
  FrameStatsCounter c(r.header());
  for (Fragment f; r.next(f);) c.add(f);
  return c.finish();
}

}  // namespace ropsim
