// The analytical model's DRAM (--fidelity approximate), tag-only: the cycle
// model's address map and row buffers (dram.h) without time of its own.
#pragma once
#include <algorithm>
#include <cstdint>
#include <vector>

#include "rtl_models/algo/bits.h"
#include "rtl_models/config/hw_config.h"
#include "rtl_models/memory/address_map.h"
#include "rtl_models/memory/dram.h"
#include "rtl_models/memory/tag_compression.h"

namespace ropsim {

/// The DRAM's address map (dram.h: channel from the interleave granule folded
/// with higher bits, bank from the row) and its row buffers, tag-only; and
/// each channel's bursts served in arrival order, twice:
///  - as fast as the channel can, as Dram::access does for requests that all
///    arrive at once: a burst starts when the data bus is free and its bank
///    is free (plus the row-miss penalty). The clock this keeps per channel
///    (bus_free) is the cycles the channel needs for its bursts so far,
///    whatever the arrival times: a lower bound (the DRAM bound).
///  - timed, by Dram::access's rule for a burst requested at a cycle
///    (set_now: the estimated cycle its fragment entered the depth test): it
///    starts no earlier than its request, its bank (plus the row-miss
///    penalty) and the channel's data bus, behind every burst requested
///    before it -- the posted write-backs and the other ROPs' reads. A
///    read's latency is the cycles from its request to its data: the
///    queueing behind the channel's backlog included. The bursts come in the
///    order the model visits the fragments (input order), so one requested
///    earlier than a burst already served waits behind it.
class DramTags : public BurstSink {
 public:
  explicit DramTags(const HwConfig::Dram& cfg) : cfg_(cfg), map_(cfg), ch_(cfg.channels) {
    for (auto& c : ch_) {
      c.open_row.assign(cfg.banks, ~uint64_t{0});
      c.bank_free.assign(cfg.banks, 0);
      c.timed_bank_free.assign(cfg.banks, 0);
    }
  }
  /// The cycle of the next bursts' request (the timed service).
  void set_now(uint64_t now) { now_ = now; }
  /// One burst of `bytes`, requested at set_now's cycle; returns a read's
  /// latency (the timed service: queueing behind the channel's earlier
  /// bursts, row miss, transfer, the read latency). A burst requested
  /// `after` cycles later (a compressed fill's data after its state bits)
  /// starts no earlier than that; its latency counts from set_now's cycle.
  uint64_t access(uint64_t addr, uint32_t bytes, bool write, Buffer b, uint64_t after) override {
    const DramAddressMap::Place at = map_.place(addr);
    const size_t ch_index = at.channel;
    Channel& c = ch_[ch_index];
    if (!write) c.read = true;
    const uint64_t row = at.row, bank = at.bank;
    uint64_t ready = c.bank_free[bank], penalty = 0;
    if (c.open_row[bank] == row) {
      ++s_.row_hits;
    } else {
      ++s_.row_misses;
      c.open_row[bank] = row;
      penalty = cfg_.row_miss_cycles;
    }
    ready += penalty;
    const uint64_t transfer = ceil_div<uint64_t>(bytes, cfg_.bytes_per_clock);
    const uint64_t start = std::max(ready, c.bus_free);
    c.bus_free = c.bank_free[bank] = start + transfer;
    c.busy += transfer;
    // Timed, as Dram::access: the bank from the request (or its previous
    // burst), the row switch in the bank, then the shared data bus.
    const uint64_t timed_start = std::max(std::max(now_ + after, c.timed_bank_free[bank]) + penalty, c.timed_bus_free);
    // Dram::access's service: from the request (or the previous burst's end)
    // to the end of the transfer.
    c.timed_service += timed_start + transfer - std::max(now_ + after, c.timed_bus_free);
    c.timed_bus_free = c.timed_bank_free[bank] = timed_start + transfer;
    if (write) {
      ++s_.writes;
      s_.bytes_written[size_t(b)] += bytes;
      return 0;
    }
    ++s_.reads;
    s_.bytes_read[size_t(b)] += bytes;
    return timed_start + transfer + cfg_.latency_cycles - now_;
  }
  /// The busiest channel's service clock (cycles).
  uint64_t max_clock() const {
    uint64_t m = 0;
    for (const auto& c : ch_) m = std::max(m, c.bus_free);
    return m;
  }
  /// The channel of a burst address.
  size_t channel_of(uint64_t addr) const { return map_.channel_of(addr); }
  /// Each channel's service clock.
  void clocks(std::vector<uint64_t>& out) const {
    out.resize(ch_.size());
    for (size_t i = 0; i < ch_.size(); ++i) out[i] = ch_[i].bus_free;
  }
  /// The busiest channel's service cycles in the timed service.
  uint64_t max_timed_service() const {
    uint64_t m = 0;
    for (const auto& c : ch_) m = std::max(m, c.timed_service);
    return m;
  }
  uint64_t max_busy() const {
    uint64_t m = 0;
    for (const auto& c : ch_) m = std::max(m, c.busy);
    return m;
  }
  /// Whether channel i served a read since the last call, and forget it.
  bool take_read(size_t i) {
    const bool r = ch_[i].read;
    ch_[i].read = false;
    return r;
  }
  size_t channels() const { return ch_.size(); }
  const DramStats& stats() const { return s_; }

 private:
  HwConfig::Dram cfg_;
  DramAddressMap map_;
  struct Channel {
    uint64_t bus_free = 0, busy = 0;
    uint64_t timed_bus_free = 0;  // the timed service's data bus
    uint64_t timed_service = 0;   // the timed service's cycles, as Dram::access counts them
    bool read = false;            // a read since the last take_reads
    std::vector<uint64_t> open_row, bank_free, timed_bank_free;
  };
  std::vector<Channel> ch_;
  uint64_t now_ = 0;
  DramStats s_;
};

}  // namespace ropsim
