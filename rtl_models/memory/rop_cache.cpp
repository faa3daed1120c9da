#include "rop_cache.h"

#include <algorithm>

#include "bits.h"

namespace ropsim {

void PostedWrites::apply(uint64_t before) {
  // Merge the ROPs' queues in (cycle, ROP) order.
  for (;;) {
    Queue* next = nullptr;
    for (auto& q : q_)
      if (!q.empty() && (!next || q.front().cycle < next->front().cycle)) next = &q;
    if (!next || next->front().cycle >= before) {
      earliest_ = next ? next->front().cycle : ~uint64_t{0};
      return;
    }
    const Write w = next->front();
    next->pop_front();
    w.cache->write(w.line, w.buf, w.cycle);
  }
}

RopCache::RopCache(const HwConfig::Cache& cfg, Dram& dram, LineSet& in_dram, PostedWrites* posted, uint32_t rop)
    : cfg_(cfg),
      dram_(dram),
      in_dram_(in_dram),
      posted_(posted),
      rop_(rop),
      sets_(cfg.size_bytes / (cfg.line_bytes * cfg.ways)),
      set_shift_(uint32_t(log2_ceil(cfg.line_bytes))),
      tags_(size_t(cfg.size_bytes / cfg.line_bytes), kInvalid),
      lru_(tags_.size(), 0),
      ways_(size_t(cfg.size_bytes / cfg.line_bytes)) {}

size_t RopCache::lookup(uint64_t line, bool& hit, uint64_t now) {
  const uint64_t l = line >> set_shift_;
  const uint64_t set = (l ^ (l >> 11) ^ (line >> 48) * 0x9e37u) & (sets_ - 1);
  const size_t base = size_t(set) * cfg_.ways;
  const uint64_t* tag = &tags_[base];
  const uint32_t n = cfg_.ways;
  for (uint32_t i = 0; i < n; ++i)
    if (tag[i] == line) {
      hit = true;
      lru_[base + i] = ++tick_;
      return base + i;
    }
  // Miss: the first invalid way, else the least recently used.
  size_t victim = base;
  for (uint32_t i = 0; i < n && tags_[victim] != kInvalid; ++i)
    if (tag[i] == kInvalid || lru_[base + i] < lru_[victim]) victim = base + i;
  hit = false;
  evict(victim, now);
  tags_[victim] = line;
  lru_[victim] = ++tick_;
  return victim;
}

void RopCache::evict(size_t way, uint64_t now) {
  if (tags_[way] == kInvalid) return;
  Way& w = ways_[way];
  if (warming_) {
    if (w.dirty) in_dram_.insert(tags_[way]);
  } else {
    ++s_.evictions;
    if (w.dirty) {
      ++s_.dirty_evictions;
      dram_.access(tags_[way], cfg_.line_bytes, true, w.buf, now);
      in_dram_.insert(tags_[way]);
    }
  }
  tags_[way] = kInvalid;
  w.dirty = false;
}

uint64_t RopCache::read(uint64_t line, Buffer b, uint64_t now) {
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
  w.buf = b;
  w.dirty = false;
  if (cfg_.fast_clear && !in_dram_.contains(line)) {
    ++s_.clear_fills;
    w.ready = now + cfg_.hit_latency_cycles;
  } else {
    w.ready = dram_.access(line, cfg_.line_bytes, false, b, now) + cfg_.hit_latency_cycles;
  }
  return w.ready;
}

void RopCache::write(uint64_t line, Buffer b, uint64_t now) {
  bool hit = false;
  Way& w = ways_[lookup(line, hit, now)];
  if (log_) ++(hit ? log_->row(now).cache_hits : log_->row(now).cache_misses);
  if (hit) {
    ++s_.write_hits[size_t(b)];
  } else {
    ++s_.write_misses[size_t(b)];
    w.buf = b;
    w.ready = now;
  }
  if (!w.dirty) ++s_.dirtied;
  w.dirty = true;
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
  }
  if (write) w.dirty = true;
}

uint64_t RopCache::flush(uint64_t now) {
  if (posted_) posted_->apply_all();
  uint64_t done = now;
  for (size_t i = 0; i < ways_.size(); ++i)
    if (Way& w = ways_[i]; tags_[i] != kInvalid && w.dirty) {
      done = std::max(done, dram_.access(tags_[i], cfg_.line_bytes, true, w.buf, now));
      in_dram_.insert(tags_[i]);
      w.dirty = false;
    }
  return done;
}

}  // namespace ropsim
