// DRAM timing model shared by all ROP units: channels with a data bus of
// bytes_per_clock, banks with one open row each, a row-miss penalty and a
// read latency (in the spirit of DRAMsys / ATTILA's memory controller, at
// burst granularity). Banks work in parallel: a row switch (precharge +
// activate) occupies its bank, not the channel's data bus, so bank-level
// parallelism hides row misses until the bus or one bank saturates. A passive model: the caches call it at the current
// cycle, in simulation-time order, and get the completion cycle back, like a
// TLM-2 loosely-timed b_transport with an annotated delay. Requests to one
// channel are served in arrival order (FCFS).
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "rtl_models/algo/bits.h"
#include "rtl_models/config/hw_config.h"
#include "rtl_models/memory/address_map.h"
#include "rtl_models/observe/attribution.h"
#include "rtl_models/observe/interval_log.h"
#include "rtl_models/observe/waveform.h"

namespace ropsim {

struct DramStats {
  std::array<uint64_t, kBuffers> bytes_read{}, bytes_written{};
  uint64_t reads = 0, writes = 0, row_hits = 0, row_misses = 0;
  uint64_t busy_cycles = 0;       ///< sum over channels of data-bus cycles
  uint64_t max_channel_busy = 0;  ///< the busiest channel's busy cycles
  /// The largest over the channels of its service cycles: the cycles in which
  /// it had a request and was serving one (in arrival order: a burst's
  /// transfer, and before it the cycles its bank was busy or switching rows
  /// with the bus idle). At least its data-bus cycles; the DRAM's own bound.
  uint64_t max_channel_service = 0;
  uint64_t last_completion = 0;  ///< cycle the last access completes

  /// Bytes read (written) over every buffer.
  uint64_t total_bytes_read() const {
    uint64_t n = 0;
    for (uint64_t b : bytes_read) n += b;
    return n;
  }
  uint64_t total_bytes_written() const {
    uint64_t n = 0;
    for (uint64_t b : bytes_written) n += b;
    return n;
  }
};

/// x / d and x % d by a shift and a mask when d is a power of two (the
/// common configs), by the divider otherwise: one access did four divisions.
class Divisor {
 public:
  Divisor() : Divisor(1) {}
  explicit Divisor(uint64_t d) : d_(d), pow2_(is_pow2(d)), shift_(log2_floor(d)) {}
  uint64_t div(uint64_t x) const { return pow2_ ? x >> shift_ : x / d_; }
  uint64_t mod(uint64_t x) const { return pow2_ ? x & (d_ - 1) : x % d_; }

 private:
  uint64_t d_;
  bool pow2_;
  int shift_;
};

/// Where an address lives in the DRAM: its channel (the interleave granule
/// folded with higher bits, so that the buffers, 2^48 apart, and tile strides
/// spread over the channels), its row within the channel, and its bank (the
/// row folded with the buffer). Written once for the cycle model's Dram and
/// the analytical model's tag-only DRAM.
class DramAddressMap {
 public:
  struct Place {
    size_t channel;
    uint64_t row, bank;
  };
  explicit DramAddressMap(const HwConfig::Dram& cfg)
      : interleave_bytes_(cfg.interleave_bytes),
        interleave_(cfg.interleave_bytes),
        channels_(cfg.channels),
        row_(cfg.row_bytes),
        banks_(cfg.banks) {}
  size_t channel_of(uint64_t addr) const {
    const uint64_t granule = interleave_.div(addr);
    return size_t(channels_.mod(granule ^ (granule >> 7) ^ (granule >> 17) ^ (addr >> 48)));
  }
  Place place(uint64_t addr) const {
    const uint64_t granule = interleave_.div(addr);
    const uint64_t local = channels_.div(granule) * interleave_bytes_ + interleave_.mod(addr);
    const uint64_t row = row_.div(local);
    return Place{channel_of(addr), row, banks_.mod(row ^ (addr >> 48))};
  }

 private:
  uint64_t interleave_bytes_;
  Divisor interleave_, channels_, row_, banks_;
};

class Dram {
 public:
  explicit Dram(const HwConfig::Dram& cfg);
  /// One burst of bytes at addr issued at cycle now; returns the cycle its
  /// data is back (reads) or written (writes).
  uint64_t access(uint64_t addr, uint32_t bytes, bool write, Buffer b, uint64_t now);
  DramStats stats() const;
  /// Also records every access's bytes in log's row of its cycle (--stats-interval).
  void log_to(IntervalLog* log) { log_ = log; }
  /// Also records, per channel, what its data bus moves (chN_bus: idle, read
  /// or write, over the burst's cycles) and its row misses so far
  /// (chN_row_misses, counted at the burst's first cycle), as signals of
  /// `scope` in wave (--vcd); before any access.
  void trace_to(Waveform& wave, const std::string& scope);
  /// Also charges every access's bytes to a draw in attr (attribution.h):
  /// the draw set last by charge_to, which the callers set before they
  /// call; settle_attribution() charges the last ones (end of the pass).
  void attribute_to(Attribution* attr) { attr_ = attr; }
  bool attributing() const { return attr_ != nullptr; }
  void charge_to(uint32_t draw) {
    if (draw == draw_) return;  // the same draw's bytes keep adding up
    if (attr_) settle_attribution();
    draw_ = draw;
  }
  uint32_t charged() const { return draw_; }
  /// Charges the bytes moved since the last charge_to to its draw: access()
  /// itself does no attribution work (the bytes are its statistics' growth).
  void settle_attribution();
  /// The host bytes the channels and banks of a DRAM of cfg take (memory_estimate.h).
  static uint64_t bytes_for(const HwConfig::Dram& cfg) {
    return uint64_t(cfg.channels) * (sizeof(Channel) + 2 * uint64_t(cfg.banks) * sizeof(uint64_t));
  }

 private:
  Attribution* attr_ = nullptr;
  uint32_t draw_ = 0;
  std::array<uint64_t, kBuffers> read_charged_{}, written_charged_{};  // s_'s bytes at the last settle
  IntervalLog* log_ = nullptr;
  Waveform* wave_ = nullptr;
  int wave_sig_ = -1;  // channel i: bus state wave_sig_ + 2 i, row misses + 1
  HwConfig::Dram cfg_;
  DramAddressMap map_;
  Divisor bus_;
  struct Channel {
    uint64_t bus_free = 0, busy = 0, row_misses = 0;
    uint64_t service = 0;             // cycles serving a request: DramStats::max_channel_service
    std::vector<uint64_t> open_row;   // per bank, ~0 = closed
    std::vector<uint64_t> bank_free;  // per bank: cycle its last access ends
  };
  std::vector<Channel> ch_;
  DramStats s_;
};

}  // namespace ropsim
