#include "rtl_models/memory/dram.h"

#include <algorithm>

namespace ropsim {

Dram::Dram(const HwConfig::Dram& cfg) : cfg_(cfg), map_(cfg), bus_(cfg.bytes_per_clock), ch_(cfg.channels) {
  for (auto& c : ch_) {
    c.open_row.assign(cfg.banks, ~uint64_t{0});
    c.bank_free.assign(cfg.banks, 0);
  }
}

uint64_t Dram::access(uint64_t addr, uint32_t bytes, bool write, Buffer b, uint64_t now) {
  const DramAddressMap::Place at = map_.place(addr);
  const size_t ch_index = at.channel;
  Channel& c = ch_[ch_index];
  const uint64_t row = at.row, bank = at.bank;
  uint64_t ready = std::max(now, c.bank_free[bank]);  // the bank may still serve an earlier access
  const bool row_hit = c.open_row[bank] == row;
  if (row_hit) {
    ++s_.row_hits;
  } else {
    ++s_.row_misses;
    ++c.row_misses;
    c.open_row[bank] = row;
    ready += cfg_.row_miss_cycles;  // precharge + activate, in the bank only
  }
  const uint64_t transfer = bus_.div(uint64_t(bytes) + cfg_.bytes_per_clock - 1);
  const uint64_t start = std::max(ready, c.bus_free);         // the data bus is shared by the banks
  c.service += start + transfer - std::max(now, c.bus_free);  // from the request or the previous burst's end
  c.bus_free = start + transfer;
  c.bank_free[bank] = start + transfer;
  c.busy += transfer;
  if (wave_) {  // a channel's bursts follow each other on its bus: their cycles only grow
    const int sig = wave_sig_ + 2 * int(ch_index);
    wave_->set(sig, start, write ? 2 : 1);
    wave_->set(sig, start + transfer, 0);
    if (!row_hit) wave_->set(sig + 1, start, c.row_misses);
  }
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

void Dram::settle_attribution() {
  for (size_t b = 0; b < size_t(kBuffers); ++b) {
    if (const uint64_t n = s_.bytes_read[b] - read_charged_[b]) attr_->dram(draw_, false, Buffer(b), n);
    if (const uint64_t n = s_.bytes_written[b] - written_charged_[b]) attr_->dram(draw_, true, Buffer(b), n);
  }
  read_charged_ = s_.bytes_read;
  written_charged_ = s_.bytes_written;
}

void Dram::trace_to(Waveform& wave, const std::string& scope) {
  wave_ = &wave;
  for (size_t i = 0; i < ch_.size(); ++i) {
    const std::string ch = "ch" + std::to_string(i);
    const int sig = wave.add_state(scope, ch + "_bus", {"idle", "read", "write"});
    wave.add_count(scope, ch + "_row_misses");
    if (i == 0) wave_sig_ = sig;
  }
}

DramStats Dram::stats() const {
  DramStats s = s_;
  for (const auto& c : ch_) {
    s.busy_cycles += c.busy;
    s.max_channel_busy = std::max(s.max_channel_busy, c.busy);
    s.max_channel_service = std::max(s.max_channel_service, c.service);
  }
  return s;
}

}  // namespace ropsim
