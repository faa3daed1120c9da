#include "rtl_models/memory/rop_cache.h"

#include <algorithm>

#include "rtl_models/algo/bits.h"

namespace ropsim {

void PostedWrites::apply(uint64_t before) {
  // Merge the ROPs' queues in (cycle, ROP) order: the queue whose front comes
  // first gives writes until its front comes after the runner-up's.
  constexpr size_t kNoQueue = ~size_t{0};
  for (;;) {
    size_t n = kNoQueue, o = kNoQueue;  // the first front, and the runner-up
    for (size_t r = 0; r < q_.size(); ++r) {
      if (q_[r].writes.empty()) continue;
      const uint64_t c = q_[r].writes.front().cycle;
      if (n == kNoQueue || c < q_[n].writes.front().cycle) {
        o = n;
        n = r;
      } else if (o == kNoQueue || c < q_[o].writes.front().cycle) {
        o = r;
      }
    }
    if (n == kNoQueue || q_[n].writes.front().cycle >= before) {
      earliest_ = n == kNoQueue ? ~uint64_t{0} : q_[n].writes.front().cycle;
      return;
    }
    // Queue n comes first while its front is before `before` and before the
    // runner-up's front (at the same cycle, a lower ROP first).
    const uint64_t oc = o == kNoQueue ? ~uint64_t{0} : q_[o].writes.front().cycle;
    PerRop& p = q_[n];
    do {
      const Write w = p.writes.front();
      p.writes.pop_front();
      p.cache->write(w.line, w.buf, w.cycle, w.owner);
      p.cache->applied(w.patch);
    } while (!p.writes.empty() && p.writes.front().cycle < before &&
             (p.writes.front().cycle < oc || (p.writes.front().cycle == oc && n < o)));
  }
}

RopCache::RopCache(const HwConfig::Cache& cfg, Dram& dram, LineSet& in_dram, PostedWrites* posted, uint32_t rop)
    : cfg_(cfg), dram_(dram), in_dram_(in_dram), posted_(posted), rop_(rop), tags_(cfg), ways_(tags_.size()) {}

size_t RopCache::lookup(uint64_t line, bool& hit, uint64_t now) {
  const size_t way = tags_.find(line, hit);
  if (!hit) {
    evict(way, now);
    tags_.install(way, line);
  }
  return way;
}

void RopCache::evict(size_t way, uint64_t now) {
  const uint64_t line = tags_.tag(way);
  if (line == CacheTags::kInvalid) return;
  Way& w = ways_[way];
  if (warming_) {
    if (w.dirty) in_dram_.insert(line);
    if (w.dirty && comp_ && comp_->compresses(w.buf)) {  // the tile leaves as a block, its state bits written
      comp_->warm_metadata(line, w.buf, true, rop_);
      uint64_t first = 0, count = 0;
      comp_->tile_lines(line, w.buf, first, count);
      for (uint64_t k = 0; k < count; ++k) {
        const uint64_t other = first + k * cfg_.line_bytes;
        const size_t ow = other == line ? CacheTags::kNone : tags_.probe(other);
        if (ow == CacheTags::kNone || !ways_[ow].dirty || ways_[ow].buf != w.buf) continue;
        in_dram_.insert(other);
        ways_[ow].dirty = false;
      }
    }
  } else {
    ++s_.evictions;
    if (w.dirty) {
      ++s_.dirty_evictions;
      if (attr_) dram_.charge_to(w.draw);  // the data's draw, whoever evicts it
      write_back(line, w.buf, now);
      // A compressed tile leaves as a block: the tile's other dirty lines
      // are written back with it (and stay, clean).
      if (comp_ && comp_->compresses(w.buf)) {
        uint64_t first = 0, count = 0;
        comp_->tile_lines(line, w.buf, first, count);
        for (uint64_t k = 0; k < count; ++k) {
          const uint64_t other = first + k * cfg_.line_bytes;
          if (other == line) continue;
          const size_t ow = tags_.probe(other);
          if (ow == CacheTags::kNone || !ways_[ow].dirty || ways_[ow].buf != w.buf) continue;
          if (attr_) dram_.charge_to(ways_[ow].draw);
          write_back(other, w.buf, now);
          ways_[ow].dirty = false;
        }
      }
    }
  }
  tags_.invalidate(way);
  w.dirty = false;
}

uint64_t RopCache::write_back(uint64_t line, Buffer b, uint64_t now) {
  if (comp_ && comp_->compresses(b)) {
    uint64_t done = now;
    // A tile holding only the clear value stays cleared (no data written):
    // a later fill of the line is a clear fill.
    if (comp_->write_back(line, b, now, rop_, done)) in_dram_.insert(line);
    return done;
  }
  if (comp_ && b == Buffer::kDepth) comp_->depth_written_back(line);  // Hi-Z alone
  in_dram_.insert(line);
  return dram_.access(line, cfg_.line_bytes, true, b, now);
}

uint64_t RopCache::read(uint64_t line, Buffer b, uint64_t now, Owner o) {
  if (posted_) posted_->apply_before(now);  // earlier cycles' writes first, in a fixed order
  bool hit = false;
  Way& w = ways_[lookup(line, hit, now)];
  if (log_) ++(hit ? log_->row(now).cache_hits : log_->row(now).cache_misses);
  if (hit) {
    ++s_.read_hits[size_t(b)];
    if (w.ready > now + cfg_.hit_latency_cycles) {
      ++s_.merged;
      return w.ready;
    }
    return now + cfg_.hit_latency_cycles;
  }
  ++s_.read_misses[size_t(b)];
  if (attr_) {
    attr_->cache_miss(o.tile);
    dram_.charge_to(o.draw);  // the fill (and its state bits) is the missing fragment's
  }
  w.buf = b;
  w.dirty = false;
  if (cfg_.fast_clear && !in_dram_.contains(line)) {
    ++s_.clear_fills;
    w.ready = now + cfg_.hit_latency_cycles;
  } else if (comp_ && comp_->compresses(b)) {
    w.ready = comp_->fill(line, b, now, rop_) + cfg_.hit_latency_cycles;
  } else {
    w.ready = dram_.access(line, cfg_.line_bytes, false, b, now) + cfg_.hit_latency_cycles;
  }
  return w.ready;
}

void RopCache::write(uint64_t line, Buffer b, uint64_t now, Owner o) {
  bool hit = false;
  Way& w = ways_[lookup(line, hit, now)];
  if (log_) ++(hit ? log_->row(now).cache_hits : log_->row(now).cache_misses);
  if (hit) {
    ++s_.write_hits[size_t(b)];
  } else {
    ++s_.write_misses[size_t(b)];
    if (attr_) attr_->cache_miss(o.tile);
    w.buf = b;
    w.ready = now;
  }
  if (!w.dirty) ++s_.dirtied, ++s_.dirtied_of[size_t(b)];
  w.dirty = true;
  w.draw = o.draw;
  if (comp_ && comp_->compresses(b)) comp_->touched(line, b);
}

void RopCache::warm(uint64_t line, bool write, Buffer b) {
  warming_ = true;
  bool hit = false;
  Way& w = ways_[lookup(line, hit, 0)];
  warming_ = false;
  if (!hit) {
    w.buf = b;
    w.ready = 0;
    w.dirty = false;
    // A read miss fills the line: a compressed surface's fill reads its tile's state bits.
    if (!write && comp_ && comp_->compresses(b) && (!cfg_.fast_clear || in_dram_.contains(line)))
      comp_->warm_metadata(line, b, false, rop_);
  }
  if (write) w.dirty = true;
}

uint64_t RopCache::flush(uint64_t now) {
  if (posted_) posted_->apply_all();
  uint64_t done = now;
  for (size_t i = 0; i < ways_.size(); ++i)
    if (Way& w = ways_[i]; tags_.tag(i) != CacheTags::kInvalid && w.dirty) {
      if (attr_) dram_.charge_to(w.draw);  // the last writer's, like an eviction
      done = std::max(done, write_back(tags_.tag(i), w.buf, now));
      w.dirty = false;
    }
  return done;
}

}  // namespace ropsim
