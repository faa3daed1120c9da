#include "rtl_models/top/memory_estimate.h"

#include <algorithm>
#include <memory>

#include "rtl_models/algo/bits.h"
#include "rtl_models/core/token.h"
#include "rtl_models/memory/cache_tags.h"
#include "rtl_models/memory/compression_model.h"
#include "rtl_models/memory/dram.h"
#include "rtl_models/memory/rop_cache.h"
#include "rtl_models/memory/tag_cache.h"
#include "rtl_models/sorter/sort_algorithm.h"
#include "rtl_models/top/rop_pipeline.h"
#include "rtl_models/units/alpha_ref_gen.h"
#include "rtl_models/units/blend_unit.h"
#include "rtl_models/units/coverage_tracker.h"
#include "rtl_models/units/depth_test.h"
#include "rtl_models/units/distributor.h"
#include "rtl_models/units/pixel_ordering.h"
#include "rtl_models/units/sample_sorter.h"
#include "rtl_models/units/trace_source.h"
#include "rtl_models/units/writeback.h"
#include "util/containers/paged_array.h"
#include "util/errors.h"
#include "util/memory_budget.h"

namespace ropsim {

static_assert(TagOnlyCache::kWayBytes == kApproxWayBytes, "kApproxWayBytes is a tag-only cache way's size");

namespace {

/// What one allocation of n bytes takes from glibc's heap: its size and an
/// 8-byte header, rounded up to 16 bytes, at least 32.
uint64_t heap_chunk(uint64_t n) { return std::max<uint64_t>(32, (n + 8 + 15) / 16 * 16); }

/// Host bytes of a PagedArray's page table over n entries (paged_array.h):
/// a pointer per page, one heap chunk.
uint64_t page_tables(uint64_t n) {
  constexpr uint64_t kPage = PagedArray<uint8_t>::kPage;
  return heap_chunk((n + kPage - 1) / kPage * PagedArray<uint8_t>::table_bytes_per_page());
}

/// What SystemC allocates for one sc_module beyond the object itself (its
/// name and its entries in the object manager and its parent's child list).
/// Measured (MemoryEstimateModel.BuiltPipelineHeapMatchesTheEstimate prints
/// each design's heap growth): with this at 0, building the 64-ROP pipeline
/// took 104 KB less heap than the other terms, which count the units' rings
/// 147 KB above their first size; the 43 KB left over its 386 units is 111
/// bytes a unit.
constexpr uint64_t kSystemCModuleBytes = 112;

/// The scheduler's bookkeeping per unit (scheduler.h): its pointer, its wake
/// list's header and a few requested cycles, its earliest cycle, its waiting
/// entry and its due bit; and the pipeline's UnitEntry and owner pointer.
constexpr uint64_t kSchedulerBytesPerUnit = sizeof(Unit*) + sizeof(std::vector<uint64_t>) + 4 * sizeof(uint64_t) +
                                            sizeof(uint64_t) + sizeof(uint32_t) + 1 + sizeof(RopPipeline::UnitEntry) +
                                            sizeof(std::unique_ptr<Unit>);

/// A SortedRing (sorted_ring.h) of elements of `elem` bytes that holds up to
/// n: a power of two >= max(16, n).
uint64_t ring_bytes(uint64_t elem, uint64_t n) { return next_pow2(std::max<uint64_t>(16, n)) * elem; }

/// FlatSet (flat_set.h) of up to n keys: a power of two >= max(16, 2n) slots.
uint64_t flat_set_bytes(uint64_t n) { return std::max<uint64_t>(16, next_pow2(2 * n)) * sizeof(uint64_t); }

/// One FIFO of the pipeline (rop_pipeline.cpp make_fifo): the object, its
/// ring and statistics, its owner's pointer and its name.
uint64_t fifo_bytes(uint32_t capacity) {
  return heap_chunk(sizeof(TokenFifo)) + heap_chunk(TokenFifo::bytes_for(capacity)) + sizeof(void*) + 32;
}

/// One unit of type U: the object and SystemC's and the scheduler's share.
template <class U>
uint64_t unit_bytes() {
  return heap_chunk(sizeof(U)) + kSystemCModuleBytes + kSchedulerBytesPerUnit;
}

/// The pixels of the screen padded to whole 8 x 8 address-map tiles.
uint64_t padded_pixels(const MemoryShape& s) { return uint64_t(ceil_div(s.width, 8u)) * ceil_div(s.height, 8u) * 64; }

/// The pipeline of one pass (rop_pipeline.cpp): its terms per ROP, and the
/// shared ones. Multi-pass methods build one pass's pipeline at a time.
struct PassCost {
  uint64_t fifos_rop = 0, tokens_rop = 0, units_rop = 0;
  uint64_t fifos_shared = 0, tokens_shared = 0, units_shared = 0;
  uint64_t token_count_rop = 0, token_count_shared = 0;  // tokens (RopPipeline::token_bound)
};

PassCost pass_cost(const HwConfig& hw, const MemoryShape& s, PassKind pass) {
  const MethodTraits& mt = traits(selection_of(s.method));
  const bool blend = is_blend_pass(pass);
  PassCost c;
  // Per ROP: its FIFOs (capacity: depth + the producer's latency) and units.
  std::vector<uint32_t> caps = {hw.distributor.fifo_depth + hw.distributor.latency_cycles,
                                hw.ordering.fifo_depth + hw.ordering.latency_cycles,
                                hw.depth_test.fifo_depth + hw.depth_test.latency_cycles};
  c.units_rop += unit_bytes<PixelOrdering>() + hw.ordering.window * sizeof(FragToken*) +
                 flat_set_bytes(hw.ordering.pixels_in_flight) +
                 ring_bytes(2 * sizeof(uint64_t), hw.ordering.pixels_in_flight);
  // The depth test's fragments waiting for their data: (ready, seq, token, killed).
  c.units_rop += unit_bytes<DepthTest>() + ring_bytes(2 * sizeof(uint64_t) + sizeof(FragToken*) + sizeof(uint64_t),
                                                      hw.depth_test.max_outstanding);
  if (blend) {
    c.units_rop += unit_bytes<BlendUnit>();
  } else {
    if (mt.tracker) {
      caps.push_back(hw.tracker.fifo_depth + hw.tracker.latency_cycles);
      c.units_rop += unit_bytes<CoverageTracker>();
    }
    if (mt.sorter) {
      caps.push_back(hw.sorter.fifo_depth + make_sorter(hw.sorter.kind, s.spp)->latency_cycles(s.spp));
      c.units_rop += unit_bytes<SampleSorter>() + heap_chunk(64);  // and its sort algorithm
    }
    if (mt.reference) {
      caps.push_back(hw.alpha_ref.fifo_depth + hw.alpha_ref.pipeline_depth +
                     ceil_div(uint32_t(s.spp) + 1, hw.alpha_ref.lanes) - 1);
      c.units_rop += unit_bytes<AlphaRefGen>();
    }
    c.units_rop += unit_bytes<Writeback>();
  }
  // The writes a ROP posts (rop_cache.h PostedWrites): its queue's first ring.
  c.units_rop += ring_bytes(4 * sizeof(uint64_t), 16) + 2 * sizeof(void*);
  // Tokens: one per fragment in flight, which the FIFOs, the ordering
  // window and the depth test's waiting fragments bound.
  uint64_t in_flight = hw.ordering.window + hw.depth_test.max_outstanding;
  for (uint32_t cap : caps) {
    c.fifos_rop += fifo_bytes(cap);
    in_flight += cap;
  }
  // Each token its own allocation, and its entries in the pool's two lists.
  const uint64_t token = heap_chunk(sizeof(FragToken)) + sizeof(FragToken*) + sizeof(std::unique_ptr<FragToken>);
  c.tokens_rop = in_flight * token;
  c.token_count_rop = in_flight;
  // Shared: the source's FIFO, the source and the distributor.
  const uint32_t src_cap = hw.source.fifo_depth + 1;
  c.fifos_shared = fifo_bytes(src_cap);
  c.tokens_shared = (uint64_t(src_cap) + 1) * token;
  c.token_count_shared = uint64_t(src_cap) + 1;
  c.units_shared =
      unit_bytes<TraceSource>() + unit_bytes<Distributor>() + uint64_t(hw.distributor.rop_units) * sizeof(TokenFifo*);
  return c;
}

void add(MemoryEstimate& e, const char* name, std::vector<std::string> keys, const char* meaning, uint64_t per_rop,
         uint64_t shared) {
  MemoryTerm t;
  t.name = name;
  t.keys = std::move(keys);
  t.meaning = meaning;
  t.per_rop_bytes = per_rop;
  t.shared_bytes = shared;
  t.bytes = per_rop * e.rops + shared;
  e.terms.push_back(t);
}

}  // namespace

const char* to_string(MemoryModel m) { return m == MemoryModel::kCycle ? "cycle" : "approximate"; }

MemoryEstimate estimate_memory(const HwConfig& hw, const MemoryShape& shape, MemoryModel model) {
  MemoryEstimate e;
  e.model = model;
  e.shape = shape;
  e.rops = hw.distributor.rop_units;
  const uint64_t ways = CacheTags::ways_of(hw.cache);
  const std::vector<std::string> kCacheKeys = {"cache.size_bytes", "cache.line_bytes"};
  const std::vector<std::string> kFifoKeys = {"distributor.fifo_depth", "ordering.fifo_depth", "depth_test.fifo_depth",
                                              "tracker.fifo_depth",     "sorter.fifo_depth",   "alpha_ref.fifo_depth",
                                              "source.fifo_depth"};
  // Most first: the depth test's window and the input FIFO hold the most tokens.
  const std::vector<std::string> kTokenKeys = {"depth_test.max_outstanding", "distributor.fifo_depth",
                                               "source.fifo_depth", "ordering.window"};
  if (model == MemoryModel::kCycle) {
    add(e, "cache_tags", kCacheKeys, "ROP cache: per line (way) its tag and LRU time (cache_tags.h)",
        ways * CacheTags::bytes_per_way(), 0);
    add(e, "cache_line_state", kCacheKeys,
        "ROP cache: per line its ready cycle, last draw, surface and dirty bit (rop_cache.h)",
        ways * RopCache::way_state_bytes() + heap_chunk(sizeof(RopCache)), 0);
    const bool comp = hw.compression.any() || hw.hiz.enable;
    add(e, "metadata_cache", {"compression.metadata_cache_bytes", "cache.line_bytes"},
        "compression and Hi-Z: the tiles' state-bit cache, per line its tag, LRU, dirty bit, ready cycle and draw",
        comp ? CompressionModel::metadata_cache_bytes(hw) : 0, 0);
    // The surfaces whose tiles the compression model tracks (compression_model.cpp).
    uint64_t tracked = 0;
    if (hw.compression.depth || hw.hiz.enable) ++tracked;
    if (hw.compression.color)
      tracked += 1 + (uses_transmittance(shape.method) ? 1 : 0) + (uses_accum(shape.method) ? 1 : 0);
    const uint64_t tables = comp ? page_tables(CompressionModel::screen_tiles(hw, shape.width, shape.height)) : 0;
    add(e, "compression_tile_state", {"compression.depth", "compression.color", "compression.tile_pixels"},
        "compression: per tracked surface the page tables of its four per-tile arrays (compressed size, its "
        "validity, state bits, pending writes); the pages of the tiles a frame touches are charged as allocated",
        0, tables * tracked * 4);
    add(e, "hiz", {"hiz.enable", "compression.tile_pixels"},
        "Hi-Z: the page table of the tiles' farthest stored depths (pages charged as allocated)", 0,
        hw.hiz.enable ? tables : 0);
    // The largest pass's pipeline (one is built at a time).
    PassCost worst;
    const PassList passes = passes_of(shape.method);
    auto sum = [&](const PassCost& c) {
      return uint64_t(e.rops) * (c.fifos_rop + c.tokens_rop + c.units_rop) + c.fifos_shared + c.tokens_shared +
             c.units_shared;
    };
    for (int i = 0; i < passes.count; ++i) {
      const PassCost c = pass_cost(hw, shape, passes.pass[i]);
      if (i == 0 || sum(c) > sum(worst)) worst = c;
    }
    e.tokens = uint64_t(e.rops) * worst.token_count_rop + worst.token_count_shared;
    add(e, "fifos", kFifoKeys,
        "the FIFOs between the units: per entry a token and its push, visible and pop cycles, and the occupancy "
        "statistics",
        worst.fifos_rop, worst.fifos_shared);
    add(e, "tokens", kTokenKeys,
        "fragment tokens (each a fragment and its work record), one per fragment the FIFOs and units can hold",
        worst.tokens_rop, worst.tokens_shared);
    add(e, "units", {"ordering.pixels_in_flight", "depth_test.max_outstanding"},
        "the units (SystemC modules and their scheduling), the pixel scoreboard and the waiting fragments",
        worst.units_rop, worst.units_shared);
    add(e, "dram", {"dram.channels", "dram.banks"}, "DRAM model: per bank its open row and the cycle it is free", 0,
        Dram::bytes_for(hw.dram) + sizeof(Dram));
  } else {
    add(e, "cache_tags", kCacheKeys, "tag-only ROP cache: per line (way) its tag and LRU time (cache_tags.h)",
        ways * CacheTags::bytes_per_way(), 0);
    add(e, "cache_line_state", kCacheKeys,
        "tag-only ROP cache: per line its fill, surface and dirty bit (approximate.cpp)",
        ways * kApproxWayBytes + heap_chunk(256), 0);
    add(e, "ordering_window", {"ordering.window"}, "per ROP the issue cycles of its last window fragments",
        heap_chunk(uint64_t(hw.ordering.window) * sizeof(double)) + 96, 0);
    add(e, "dram", {"dram.channels", "dram.banks"}, "tag-only DRAM: per bank its open row and the cycle it is free", 0,
        Dram::bytes_for(hw.dram));
    add(e, "pixel_retirements", {}, "per pixel of the screen its last fragment's estimated retirement", 0,
        padded_pixels(shape) * sizeof(double));
    add(e, "fragment_records", {}, "the functional pass's fragment records: two batches handed to the model", 0,
        2 * kApproxBatchRecords * kApproxRecordBytes);
    const bool comp = hw.compression.any();
    add(e, "metadata_cache", {"compression.metadata_cache_bytes", "cache.line_bytes"},
        "compression: the tiles' state-bit cache, tag-only: per line its tag, LRU and dirty bit (counted as the "
        "cycle model's, which also keeps a ready cycle and a draw)",
        comp ? CompressionModel::metadata_cache_bytes(hw) : 0, 0);
    uint64_t compressed = 0;  // the surfaces compressed (tag_compression.cpp)
    if (hw.compression.depth) ++compressed;
    if (hw.compression.color)
      compressed += 1 + (uses_transmittance(shape.method) ? 1 : 0) + (uses_accum(shape.method) ? 1 : 0);
    const uint64_t tables =
        comp || hw.hiz.enable ? page_tables(CompressionModel::screen_tiles(hw, shape.width, shape.height)) : 0;
    add(e, "compression_tile_state", {"compression.depth", "compression.color", "compression.tile_pixels"},
        "compression: per compressed surface the page tables of its three per-tile arrays (compressed size, its "
        "validity, state bits); the pages of the tiles a frame touches are charged as allocated",
        0, tables * compressed * 3);
    add(e, "hiz", {"hiz.enable", "compression.tile_pixels"},
        "Hi-Z: the page table of the tiles' farthest stored depths (pages charged as allocated)", 0,
        hw.hiz.enable ? tables : 0);
  }
  for (const MemoryTerm& t : e.terms) {
    e.per_rop_bytes += t.per_rop_bytes;
    e.shared_bytes += t.shared_bytes;
    e.model_bytes += t.bytes;
  }
  e.total_bytes = e.model_bytes * std::max<uint32_t>(1, shape.copies);
  return e;
}

std::vector<std::string> MemoryEstimate::costliest_keys(size_t n) const {
  std::vector<const MemoryTerm*> by_size;
  for (const MemoryTerm& t : terms)
    if (t.bytes > 0) by_size.push_back(&t);
  std::stable_sort(by_size.begin(), by_size.end(),
                   [](const MemoryTerm* a, const MemoryTerm* b) { return a->bytes > b->bytes; });
  std::vector<std::string> keys;
  bool per_rop = false;
  for (size_t i = 0; i < by_size.size() && i < n; ++i) {
    for (const std::string& k : by_size[i]->keys)
      if (keys.size() < 4 && std::find(keys.begin(), keys.end(), k) == keys.end()) keys.push_back(k);
    per_rop = per_rop || by_size[i]->per_rop_bytes > 0;
  }
  if (per_rop && rops > 1) keys.push_back("distributor.rop_units");
  return keys;
}

void check_model_memory(const HwConfig& hw, const MemoryEstimate& e) {
  const MemoryBudget& b = memory_budget();
  const uint64_t left = b.limit() > b.used() ? b.limit() - b.used() : 0;
  if (b.limit() == 0 || e.total_bytes <= left) return;
  const std::vector<std::string> keys = e.costliest_keys();
  // Where the costliest keys were set: the overrides that set them, else the file.
  std::string where;
  for (const std::string& a : hw.overrides)
    for (const std::string& k : keys)
      if (a.compare(0, k.size() + 1, k + "=") == 0) where += (where.empty() ? "--hw-set " : ", --hw-set ") + a;
  if (where.empty()) where = hw.name;
  std::string parts;
  std::vector<const MemoryTerm*> by_size;
  for (const MemoryTerm& t : e.terms) by_size.push_back(&t);
  std::stable_sort(by_size.begin(), by_size.end(),
                   [](const MemoryTerm* x, const MemoryTerm* y) { return x->bytes > y->bytes; });
  for (size_t i = 0; i < 2 && i < by_size.size(); ++i)
    parts += std::string(i ? ", " : "") + by_size[i]->name + " " + format_bytes(by_size[i]->bytes);
  std::string copies;
  if (e.shape.copies > 1) copies = " x " + std::to_string(e.shape.copies) + " workers";
  std::string key_list;
  for (const std::string& k : keys) key_list += (key_list.empty() ? "" : ", ") + k;
  throw UserError("memory limit: " + where + ": the " + to_string(e.model) + " model of this design needs " +
                  format_bytes(e.total_bytes) + " (" + std::to_string(e.rops) + " ROPs x " +
                  format_bytes(e.per_rop_bytes) + " + " + format_bytes(e.shared_bytes) + " shared" + copies + "; " +
                  parts + "), over what --memory-limit " + format_bytes(b.limit()) + " leaves (" + format_bytes(left) +
                  "); the keys that cost the most: " + key_list);
}

}  // namespace ropsim
