// The sections a timed run's report shares with the others (cycle, sampled
// and approximate): units and their activities, the ROP caches, the DRAM,
// compression and Hi-Z, the bottleneck, and the cycle model's and the
// analytical model's "timing" sections.
#pragma once
#include <nlohmann/json.hpp>
#include <string>

#include "rtl_models/functional/counters.h"
#include "rtl_models/memory/compression_model.h"
#include "rtl_models/memory/dram.h"
#include "rtl_models/memory/rop_cache.h"
#include "sim/fidelity/approximate/approximate.h"
#include "sim/fidelity/common/bottleneck.h"
#include "sim/fidelity/cycle/cycle_run.h"
#include "sim/report/report_fields.h"

namespace ropsim {

/// A unit instance's identity (cycle and sampled reports).
void put_unit_identity(Fields j, const UnitReport& u);
/// A unit instance's cycles per activity (cycle and sampled reports).
void put_unit_activity(Fields j, const UnitReport& u, uint64_t total_cycles);
/// The ROP caches' figures, summed over the ROPs (cycle and approximate reports).
void put_cache_stats(Fields cache, const CacheStats& sum, uint32_t listed);
/// The DRAM's bytes per buffer and in all, its bursts and row hits.
void put_dram_traffic(Fields dram, const DramStats& d, uint32_t listed);
/// Surface compression's traffic and Hi-Z.
void put_compression_traffic(Fields c, const CompressionTraffic& s, const HwConfig& hw);
/// The summary's line on compression and Hi-Z (cycle and approximate).
std::string compression_summary(const CompressionTraffic& c);
/// timing.bottleneck*: the class and its line, and every bound beside it.
void put_bottleneck(Fields t, const Bottleneck& b);
/// The "timing" section: every timing figure with its unit and meaning.
void put_cycle_stats(Fields t, const CycleStats& s);
nlohmann::ordered_json cycle_stats_to_json(const CycleStats& s);
/// The bottleneck as one line.
std::string format_bottleneck(const CycleStats& s);
/// The analytical model's "timing" section.
void put_approx_stats(Fields t, const ApproxStats& s, const Counters& c);

}  // namespace ropsim
