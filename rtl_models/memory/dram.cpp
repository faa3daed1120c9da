#include "dram.h"

#include <algorithm>

namespace ropsim {

Dram::Dram(const HwConfig::Dram& cfg)
    : cfg_(cfg),
      interleave_(cfg.interleave_bytes),
      channels_(cfg.channels),
      row_(cfg.row_bytes),
      banks_(cfg.banks),
      bus_(cfg.bytes_per_clock),
      ch_(cfg.channels) {
  for (auto& c : ch_) {
    c.open_row.assign(cfg.banks, ~uint64_t{0});
    c.bank_free.assign(cfg.banks, 0);
  }
}

uint64_t Dram::access(uint64_t addr, uint32_t bytes, bool write, Buffer b, uint64_t now) {
  const uint64_t granule = interleave_.div(addr);
  // Channel from the granule, folded with higher bits so that the three
  // buffers (2^48 apart) and tile strides spread over the channels.
  const uint64_t ch_index = channels_.mod(granule ^ (granule >> 7) ^ (granule >> 17) ^ (addr >> 48));
  Channel& c = ch_[ch_index];
  const uint64_t local = channels_.div(granule) * cfg_.interleave_bytes + interleave_.mod(addr);
  const uint64_t row = row_.div(local);
  const uint64_t bank = banks_.mod(row ^ (addr >> 48));
  uint64_t ready = std::max(now, c.bank_free[bank]);  // the bank may still serve an earlier access
  if (c.open_row[bank] == row) {
    ++s_.row_hits;
  } else {
    ++s_.row_misses;
    c.open_row[bank] = row;
    ready += cfg_.row_miss_cycles;  // precharge + activate, in the bank only
  }
  const uint64_t transfer = bus_.div(uint64_t(bytes) + cfg_.bytes_per_clock - 1);
  const uint64_t start = std::max(ready, c.bus_free);  // the data bus is shared by the banks
  c.bus_free = start + transfer;
  c.bank_free[bank] = start + transfer;
  c.busy += transfer;
  const uint64_t done = start + transfer + (write ? 0 : cfg_.latency_cycles);
  if (write) {
    ++s_.writes;
    s_.bytes_written[size_t(b)] += bytes;
    if (log_) log_->row(now).dram_bytes_written[size_t(b)] += bytes;
  } else {
    ++s_.reads;
    s_.bytes_read[size_t(b)] += bytes;
    if (log_) log_->row(now).dram_bytes_read[size_t(b)] += bytes;
  }
  s_.last_completion = std::max(s_.last_completion, done);
  return done;
}

DramStats Dram::stats() const {
  DramStats s = s_;
  for (const auto& c : ch_) {
    s.busy_cycles += c.busy;
    s.max_channel_busy = std::max(s.max_channel_busy, c.busy);
  }
  return s;
}

}  // namespace ropsim
