// The ROP hardware configuration: every parameter declared once with its
// section, key, unit, range, default and one-line hardware meaning
// (docs/config.md is generated from the same table: `ropsim config --markdown`).
// Latencies are cycles of the ROP clock; they are converted to sc_time once,
// by the Clock of the pipeline.
#pragma once
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#include "rtl_models/algo/blend.h"
#include "rtl_models/algo/compression_format.h"
#include "rtl_models/algo/numerics.h"
#include "util/errors.h"

namespace ropsim {

enum class SorterKind { kBitonic, kRank, kSerial };
enum class Interleave { kDiagonal, kRow };

const char* to_string(SorterKind k);
const char* to_string(Interleave k);

struct HwConfig {
  struct Clock {
    double frequency_ghz = 1.5;
  } clock;
  struct Source {
    uint32_t fragments_per_clock = 4;
    uint32_t fifo_depth = 16;
  } source;
  struct Distributor {
    uint32_t rop_units = 4;
    uint32_t tile_pixels = 16;
    Interleave interleave = Interleave::kDiagonal;
    uint32_t fragments_per_clock = 4;
    uint32_t latency_cycles = 1;
    uint32_t fifo_depth = 16;
  } distributor;
  struct Ordering {
    uint32_t pixels_in_flight = 128;
    uint32_t window = 8;
    uint32_t latency_cycles = 1;
    uint32_t fifo_depth = 4;
  } ordering;
  struct DepthTest {
    uint32_t samples_per_clock = 16;
    uint32_t latency_cycles = 2;
    uint32_t max_outstanding = 32;
    uint32_t fifo_depth = 4;
  } depth_test;
  struct Tracker {
    uint32_t latency_cycles = 1;
    uint32_t fifo_depth = 4;
  } tracker;
  struct Sorter {
    SorterKind kind = SorterKind::kBitonic;
    uint32_t fifo_depth = 4;
  } sorter;
  struct AlphaRef {
    uint32_t lanes = 16;
    uint32_t pipeline_depth = 4;
    uint32_t fifo_depth = 4;
  } alpha_ref;
  struct Writeback {
    uint32_t samples_per_clock = 16;
    uint32_t latency_cycles = 2;
  } writeback;
  /// The blend unit of the blend passes (wboit, total alpha, accumulation)
  /// and its render targets' formats (which the functional ROP also uses).
  struct Blend {
    uint32_t samples_per_clock = 16;
    uint32_t latency_cycles = 4;
    BlendFormats formats;
  } blend;
  struct Cache {
    uint32_t size_bytes = 65536;
    uint32_t line_bytes = 64;
    uint32_t ways = 8;
    uint32_t hit_latency_cycles = 2;
    bool fast_clear = true;
  } cache;
  struct Dram {
    uint32_t channels = 4;
    uint32_t bytes_per_clock = 32;
    uint32_t latency_cycles = 150;
    uint32_t banks = 16;
    uint32_t row_bytes = 2048;
    uint32_t row_miss_cycles = 40;
    uint32_t interleave_bytes = 256;
  } dram;
  /// Lossless surface compression (compression.h): depth planes, MSAA
  /// colour (and blend-target) fragment compression, per memory tile, with
  /// per-tile state bits held in a metadata cache of each ROP.
  struct Compression {
    bool depth = true;
    bool color = true;
    uint32_t tile_pixels = 16;
    uint32_t size_classes = 3;
    uint32_t depth_planes = 4;
    DepthEncoder depth_encoder = DepthEncoder::kPlane;
    uint32_t color_k = 4;
    uint32_t metadata_cache_bytes = 16384;
    uint32_t compress_latency_cycles = 8;
    uint32_t decompress_latency_cycles = 8;
    bool any() const { return depth || color; }
    CompressionSetup setup() const {
      return CompressionSetup{depth, color,
                              CompressionFormat{tile_pixels, size_classes, depth_planes, color_k, depth_encoder}};
    }
  } compression;
  /// Hierarchical Z: per memory tile (compression.tile_pixels) the farthest
  /// stored depth, on chip; a fragment whose samples all lie behind it is
  /// rejected before its per-sample depths are read.
  struct HiZ {
    bool enable = true;
  } hiz;
  /// The datapath widths ([numerics]); the same for every fidelity. A run's
  /// --hash-bits, --alpha-bits and --surface-id-bits override them.
  Numerics numerics;

  std::string name = "built-in defaults";  ///< file the config came from
  /// The "section.key=value" overrides applied over `name`, in order (so that
  /// a constraint they break names them).
  std::vector<std::string> overrides;
};

/// A bad configuration file, key or value: the message names the file and key.
class ConfigError : public UserError {
 public:
  using UserError::UserError;
};

/// One declared parameter (for the parser, the docs and the report).
struct ParamInfo {
  std::string key;      ///< "section.key"
  std::string unit;     ///< "cycles", "bytes", "fragments/clock", ...
  std::string meaning;  ///< one line
  std::string range;    ///< allowed values, human-readable
  std::string default_value;
  std::string basis;  ///< what the default rests on: "part: ...", "paper: ..." or "assumption..."
};
const std::vector<ParamInfo>& hw_params();

/// One parameter's value, typed: integers, reals, booleans, names (enums).
using HwValue = std::variant<int64_t, double, bool, std::string>;
/// Every parameter of cfg in table order (hw_params()), with its value.
void for_each_hw_value(const HwConfig& cfg, const std::function<void(const ParamInfo&, const HwValue&)>& fn);
/// A short digest of the design: FNV-1a 64 over every "section.key=value"
/// line of the resolved design (numerics included), the same on every
/// machine; `hw_digest_hex` gives its 8 hex digits (default output names).
uint64_t hw_config_digest(const HwConfig& cfg);
std::string hw_digest_hex(const HwConfig& cfg);

/// Reads a TOML file over the defaults (keys it omits keep their defaults) and
/// checks the result as a whole (validate_hw_config). Unknown sections or
/// keys, wrong types, out-of-range values and broken constraints throw
/// ConfigError naming the file and key.
HwConfig load_hw_config(const std::string& path);
/// resolve_hw_config of a design file's text; name stands for the file in errors.
HwConfig parse_hw_config(const std::string& text, const std::string& name,
                         const std::vector<std::string>& overrides = {});
/// The design of a run: the design file `path` (the built-in defaults when
/// empty), then every "section.key=value" override in order, then the
/// cross-parameter constraints once, on the result -- so overrides that are
/// only valid together (cache.size_bytes and cache.ways) are accepted. A bad
/// override's error names it ("--hw-set cache.ways=3: ..."). With overrides,
/// the name is "PATH with --hw-set".
HwConfig resolve_hw_config(const std::string& path, const std::vector<std::string>& overrides);
/// Parses and range-checks one "section.key=value" (as on the command line)
/// and only then applies it to cfg, recording it in cfg.overrides; a rejected
/// override throws ConfigError naming it and leaves cfg unchanged. The
/// cross-parameter constraints are not checked here: call validate_hw_config
/// after the last override (resolve_hw_config does).
void apply_hw_override(HwConfig& cfg, const std::string& assignment);
/// Checks cross-parameter constraints (e.g. cache geometry); throws ConfigError
/// naming the overrides that set the keys involved, or else cfg.name.
void validate_hw_config(const HwConfig& cfg);
/// The config as TOML text (every key, resolved); numbers print with the
/// fewest digits that read back as the same value.
std::string hw_config_to_toml(const HwConfig& cfg);
/// docs/config.md's parameter table.
std::string hw_params_markdown();

}  // namespace ropsim
