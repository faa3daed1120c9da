#include "rtl_models/functional/breakdown.h"

#include <algorithm>

namespace ropsim {

const std::vector<StatDesc>& pixel_map_descs() {
  static const std::vector<StatDesc> d = {
#define ROPSIM_X(name, unit, meaning) {#name, unit, meaning},
      ROPSIM_PIXEL_MAPS(ROPSIM_X)
#undef ROPSIM_X
  };
  return d;
}

RunBreakdown::RunBreakdown(const TraceHeader& h, bool per_draw, bool per_pixel)
    : width_(h.width), height_(h.height), per_draw_(per_draw), per_pixel_(per_pixel), tiles_(h.width, h.height) {}

void RunBreakdown::add(const Fragment& f, const Counters& d) {
  if (per_draw_) {
    if (!last_draw_ || last_id_ != f.draw_id) {
      last_draw_ = &draws_[f.draw_id];  // std::map: references stay valid
      last_id_ = f.draw_id;
    }
    last_draw_->counters += d;
  }
  if (per_pixel_) {
    Tile& t = tiles_.get(f.x, f.y, [](uint32_t, uint32_t) { return std::make_unique<Tile>(); });
    const size_t p = size_t(f.y & 7u) * 8 + (f.x & 7u);
#define ROPSIM_X(name, unit, meaning) t.v[size_t(PixelMap::name)][p] += uint32_t(d.name);
    ROPSIM_PIXEL_MAPS(ROPSIM_X)
#undef ROPSIM_X
  }
}

void RunBreakdown::add_cycles(uint32_t draw, uint64_t cycles) {
  if (per_draw_) draws_[draw].cycles += cycles;
}

void RunBreakdown::add_dram(uint32_t draw, const std::array<uint64_t, kBuffers>& read,
                            const std::array<uint64_t, kBuffers>& written) {
  if (!per_draw_) return;
  Draw& d = draws_[draw];
  for (size_t b = 0; b < size_t(kBuffers); ++b) {
    d.dram_read[b] += read[b];
    d.dram_written[b] += written[b];
  }
}

RunBreakdown::Draw RunBreakdown::total() const {
  Draw t;
  for (const auto& [id, d] : draws_) {
    t.counters += d.counters;
    t.cycles += d.cycles;
    for (size_t b = 0; b < size_t(kBuffers); ++b) {
      t.dram_read[b] += d.dram_read[b];
      t.dram_written[b] += d.dram_written[b];
    }
  }
  return t;
}

void RunBreakdown::row(PixelMap m, uint32_t y, float* out) const {
  std::fill(out, out + width_, 0.0f);
  for (uint32_t x0 = 0; x0 < width_; x0 += 8)
    if (const Tile* t = tiles_.find(x0, y))
      for (uint32_t i = 0; i < 8 && x0 + i < width_; ++i) out[x0 + i] = float(t->v[size_t(m)][size_t(y & 7u) * 8 + i]);
}

uint64_t RunBreakdown::sum(PixelMap m) const {
  uint64_t s = 0;
  tiles_.for_each([&](uint32_t, uint32_t, const Tile& t) {
    for (uint32_t v : t.v[size_t(m)]) s += v;
  });
  return s;
}

uint32_t RunBreakdown::max(PixelMap m) const {
  uint32_t s = 0;
  tiles_.for_each([&](uint32_t, uint32_t, const Tile& t) {
    for (uint32_t v : t.v[size_t(m)]) s = std::max(s, v);
  });
  return s;
}

}  // namespace ropsim
