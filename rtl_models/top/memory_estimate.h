// The host memory a design's timing model takes, estimated from the design's
// parameters before the model is built: every structure the model allocates,
// each a named term in bytes, per ROP and in total. Each structure states its
// own cost (CacheTags::bytes_per_way, RopCache::way_state_bytes,
// TimedFifo::bytes_for, Dram::bytes_for, CompressionModel's), so the estimate
// follows the code; tests/test_memory_estimate.cpp measures it against the
// peak resident memory of real runs (docs/config.md "Memory estimate").
//
// The estimate is of the model alone: the functional ROP's per-sample state,
// the image and the input are charged to --memory-limit by their own owners
// as they grow (sample_store.h, image.h), and the process's own code and
// libraries are not counted. Nor are the lines DRAM holds (line_set.h), a bit
// per line of the touched surfaces, which grow with the scene as the
// surfaces do (1/512 of their bytes at 64-byte lines). run_cycle (and the approximate and sampled
// fidelities) charge it to --memory-limit before they build anything, and
// refuse a design that does not fit (check_model_memory).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "rtl_models/config/hw_config.h"
#include "rtl_models/functional/method.h"

namespace ropsim {

/// Which model the estimate is for.
enum class MemoryModel {
  kCycle,        ///< the SystemC pipeline (--fidelity cycle; one per sampled worker)
  kApproximate,  ///< the analytical model's tag-only caches and DRAM (--fidelity approximate)
};

/// What of the run besides the design the model's size depends on: the screen
/// (Hi-Z, the compression state and the lines DRAM holds are per memory
/// tile), the samples per pixel and the method (its passes, its units and
/// its surfaces). `ropsim config` assumes the defaults below.
struct MemoryShape {
  uint32_t width = 1024, height = 1024;
  int spp = 16;
  Method method = Method::kLk;
  /// Copies of the model alive at once: the sampled fidelity's worker
  /// processes, each building its own pipeline.
  uint32_t copies = 1;
};

/// One structure of the model.
struct MemoryTerm {
  std::string name;               ///< "cache_tags", ...
  std::string meaning;            ///< one line
  std::vector<std::string> keys;  ///< the design keys it grows with ("cache.size_bytes", "cache.line_bytes")
  uint64_t per_rop_bytes = 0;     ///< in each ROP (0: a shared structure)
  uint64_t shared_bytes = 0;      ///< once for the design, not per ROP
  uint64_t bytes = 0;             ///< one copy of the model: per_rop_bytes x ROPs + shared_bytes
};

struct MemoryEstimate {
  MemoryModel model = MemoryModel::kCycle;
  MemoryShape shape;
  uint32_t rops = 1;
  std::vector<MemoryTerm> terms;  ///< every structure, in the model's order
  uint64_t per_rop_bytes = 0;     ///< the per-ROP terms of one ROP
  uint64_t shared_bytes = 0;      ///< the shared terms
  uint64_t model_bytes = 0;       ///< one copy: per_rop_bytes x ROPs + shared_bytes
  uint64_t total_bytes = 0;       ///< every copy: model_bytes x shape.copies (what is charged)
  uint64_t tokens = 0;            ///< cycle: fragment tokens of the largest pass (RopPipeline::token_bound)
  /// The design keys of the terms that cost the most (most first, the keys
  /// of at most `n` terms, at most four, each once; and distributor.rop_units
  /// when a per-ROP term is among them): what to change to make it smaller.
  std::vector<std::string> costliest_keys(size_t n = 2) const;
};

/// The memory estimate of design hw's model for a run of `shape`: every term
/// in bytes. The one place the model's memory is computed.
MemoryEstimate estimate_memory(const HwConfig& hw, const MemoryShape& shape, MemoryModel model = MemoryModel::kCycle);

const char* to_string(MemoryModel m);

/// Refuses (UserError, one line) a model whose estimate does not fit in what
/// --memory-limit leaves: the line names the design (its file, or the
/// --hw-set overrides of the costliest keys), the estimate, the limit and the
/// keys that cost the most. Charges nothing.
void check_model_memory(const HwConfig& hw, const MemoryEstimate& e);

/// The bytes of a TagOnlyCache way (tag_cache.h; memory_estimate.cpp checks
/// it) and of a FragRec record of the approximate model
/// (sim/fidelity/approximate/approximate.cpp, which checks it with
/// static_assert: it sits above this layer).
constexpr uint64_t kApproxWayBytes = 24;
constexpr uint64_t kApproxRecordBytes = 48;
/// The approximate model's fragment records: two batches of this many
/// (approximate.cpp's kBatch, checked there).
constexpr uint64_t kApproxBatchRecords = uint64_t{1} << 15;

}  // namespace ropsim
