#include "rtl_models/config/hw_param_table.h"

#include <toml++/toml.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <functional>
#include <initializer_list>
#include <iterator>
#include <sstream>
#include <system_error>
#include <utility>

#include "rtl_models/algo/bits.h"
#include "util/errors.h"
#include "util/toml_guard.h"

namespace ropsim {

namespace hw_detail {

namespace {

/// The formats a blend target of the kind may have.
std::vector<TargetFormat> formats_of(Kind k) {
  if (k == Kind::kTransFormat) return {TargetFormat::kR16F, TargetFormat::kR32F};
  return {TargetFormat::kRGBA16F, TargetFormat::kRGBA32F};
}

}  // namespace

#define U32(sec, k, unit, lo, hi, pow2, meaning)                                                         \
  Param {                                                                                                \
#sec "." #k, unit, Kind::kU32, lo, hi, pow2, meaning, [](HwConfig & c) -> void* { return &c.sec.k; } \
  }
#define I32(sec, k, unit, lo, hi, meaning)                                                                \
  Param {                                                                                                 \
#sec "." #k, unit, Kind::kInt, lo, hi, false, meaning, [](HwConfig & c) -> void* { return &c.sec.k; } \
  }
#define FIELD(sec, k) [](HwConfig& c) -> void* { return &c.sec.k; }

const std::vector<Param>& params() {
  static const std::vector<Param> p = {
      {"clock.frequency_ghz", "GHz", Kind::kReal, 0.01, 10.0, false,
       "ROP clock; converts cycles to frame time and bytes/clock to GB/s", FIELD(clock, frequency_ghz)},
      U32(source, fragments_per_clock, "fragments/clock", 1, 64, false,
          "rasterizer-to-ROP interface rate: fragments the trace source delivers per clock"),
      U32(source, fifo_depth, "entries", 1, 4096, false, "FIFO between the trace source and the distributor"),
      U32(distributor, rop_units, "units", 1, 64, false, "number of ROP units (each a full pipeline with its cache)"),
      U32(distributor, tile_pixels, "pixels", 8, 1024, true,
          "side of the square screen tiles owned by one ROP (a multiple of the 8-pixel memory tile)"),
      {"distributor.interleave", "-", Kind::kInterleave, 0, 0, false,
       "tile-to-ROP map: diagonal = (tx + ty) mod N, row = (tx + ty * tiles_x) mod N", FIELD(distributor, interleave)},
      U32(distributor, fragments_per_clock, "fragments/clock", 1, 64, false,
          "fragments the distributor routes per clock (in order; a full ROP FIFO blocks it)"),
      U32(distributor, latency_cycles, "cycles", 1, 64, false, "routing latency, input to ROP FIFO"),
      U32(distributor, fifo_depth, "entries", 1, 4096, false, "input FIFO of each ROP (distributor to pixel ordering)"),
      U32(ordering, pixels_in_flight, "pixels", 1, 4096, false,
          "scoreboard size: distinct pixels between issue and retire in one ROP"),
      U32(ordering, window, "fragments", 1, 256, false,
          "fragments the ordering unit looks at; one of another pixel may overtake a blocked one"),
      U32(ordering, latency_cycles, "cycles", 1, 64, false, "scoreboard lookup latency, issue to depth test"),
      U32(ordering, fifo_depth, "entries", 1, 4096, false, "FIFO from pixel ordering to the depth test"),
      U32(depth_test, samples_per_clock, "samples/clock", 1, 64, false,
          "depth comparators: a fragment with c covered samples occupies ceil(c / this) clocks"),
      U32(depth_test, latency_cycles, "cycles", 1, 64, false, "compare latency after the stored depth arrives"),
      U32(depth_test, max_outstanding, "fragments", 1, 1024, false,
          "fragments waiting for their pixel state from the cache (hit-under-miss window)"),
      U32(depth_test, fifo_depth, "entries", 1, 4096, false, "FIFO from the depth test to the next unit"),
      U32(tracker, latency_cycles, "cycles", 1, 64, false, "surface-tracker update latency (one fragment per clock)"),
      U32(tracker, fifo_depth, "entries", 1, 4096, false, "FIFO from the tracker to the sorter"),
      {"sorter.kind", "-", Kind::kSorter, 0, 0, false,
       "bitonic (log2 N (log2 N + 1) / 2 pipelined stages), rank (N^2 comparators, 1 clock) or serial (m clocks)",
       FIELD(sorter, kind)},
      U32(sorter, fifo_depth, "entries", 1, 4096, false, "FIFO from the sorter to the alpha-reference generator"),
      U32(alpha_ref, lanes, "hashes/clock", 1, 64, false,
          "CalcAlphaRef hash lanes: m references take ceil(m / lanes) clocks"),
      U32(alpha_ref, pipeline_depth, "cycles", 1, 64, false, "hash pipeline depth (four multiply-xor rounds)"),
      U32(alpha_ref, fifo_depth, "entries", 1, 4096, false, "FIFO from the alpha-reference generator to writeback"),
      U32(writeback, samples_per_clock, "samples/clock", 1, 64, false, "opacity tests and sample writes per clock"),
      U32(writeback, latency_cycles, "cycles", 1, 64, false, "writeback latency; the pixel retires after it"),
      U32(blend, samples_per_clock, "samples/clock", 1, 64, false,
          "blend unit throughput: samples blended (read-modify-write of each target) per clock"),
      U32(blend, latency_cycles, "cycles", 1, 64, false,
          "blend unit latency (decode, add or multiply, encode); the pixel "
          "retires after it"),
      {"blend.transmittance_format", "-", Kind::kTransFormat, 0, 0, false,
       "transmittance render target (product of 1 - alpha: total alpha, wboit revealage), per sample",
       FIELD(blend, formats.transmittance)},
      {"blend.accum_format", "-", Kind::kAccumFormat, 0, 0, false,
       "accumulation render target (sum of alpha-weighted colour and alpha: depth-based, wboit), per sample",
       FIELD(blend, formats.accum)},
      U32(cache, size_bytes, "bytes", 256, 1u << 30, true,
          "ROP cache capacity per ROP unit (depth, colour, tracker lines)"),
      U32(cache, line_bytes, "bytes", 16, 4096, true, "cache line and DRAM burst size"),
      U32(cache, ways, "ways", 1, 64, false, "set associativity (LRU replacement)"),
      U32(cache, hit_latency_cycles, "cycles", 1, 1000, false, "tag lookup and data read on a hit"),
      {"cache.fast_clear", "-", Kind::kBool, 0, 0, false,
       "lines never written to DRAM read as the clear value without a DRAM access", FIELD(cache, fast_clear)},
      U32(dram, channels, "channels", 1, 64, false, "independent DRAM channels shared by all ROPs"),
      U32(dram, bytes_per_clock, "bytes/clock", 1, 1u << 20, false,
          "peak bytes per ROP clock per channel (GB/s = this x channels x clock GHz)"),
      U32(dram, latency_cycles, "cycles", 0, 100000, false, "read latency after the data burst"),
      U32(dram, banks, "banks", 1, 256, false, "banks per channel, each with one open row"),
      U32(dram, row_bytes, "bytes", 64, 1u << 20, true, "row (page) size per bank"),
      U32(dram, row_miss_cycles, "cycles", 0, 100000, false,
          "extra cycles to close and open a row on a row-buffer miss"),
      U32(dram, interleave_bytes, "bytes", 16, 1u << 20, true, "address interleave granule between channels"),
      {"compression.depth", "-", Kind::kBool, 0, 0, false,
       "lossless depth compression: per memory tile up to depth_planes planes (found as depth_encoder says) and a "
       "per-sample selector, else uncompressed",
       FIELD(compression, depth)},
      {"compression.color", "-", Kind::kBool, 0, 0, false,
       "lossless MSAA colour compression of the colour buffer and the blend targets: per pixel its k <= color_k "
       "distinct values plus a per-sample index, else uncompressed",
       FIELD(compression, color)},
      U32(compression, tile_pixels, "pixels", 8, 64, true,
          "pixels of a memory tile (whole rows of the 8 x 8 address-map tile, all samples): the unit compressed, "
          "the unit of the state bits and of Hi-Z"),
      U32(compression, size_classes, "classes", 1, 4, false,
          "block sizes a tile of U bytes is stored in: U, U/2, ..., U/2^(classes-1) (3: full, 1/2, 1/4)"),
      U32(compression, depth_planes, "planes", 1, 8, false, "most plane equations in a compressed depth tile"),
      {"compression.depth_encoder", "-", Kind::kDepthEncoder, 0, 0, false,
       "how a depth tile's planes are found: plane = the rasterizer's planes of the primitives whose samples the "
       "tile holds (a GPU's plane encoder), fit = planes fitted to the stored depths with residuals",
       FIELD(compression, depth_encoder)},
      U32(compression, color_k, "colours", 1, 8, false,
          "K: most distinct colours per pixel in a compressed colour tile (index ceil(log2 K) bits a sample)"),
      U32(compression, metadata_cache_bytes, "bytes", 64, 1u << 24, true,
          "per-ROP cache of the tiles' state bits (its lines are cache.line_bytes; misses and dirty evictions are "
          "DRAM traffic)"),
      U32(compression, compress_latency_cycles, "cycles", 0, 10000, false,
          "compressor latency: a compressible line's write to DRAM leaves this much later"),
      U32(compression, decompress_latency_cycles, "cycles", 0, 10000, false,
          "decompressor latency, added to a fill from a compressed tile"),
      {"hiz.enable", "-", Kind::kBool, 0, 0, false,
       "hierarchical Z: a per-tile conservative farthest depth on chip rejects fragments wholly behind it before "
       "their depths are read",
       FIELD(hiz, enable)},
      I32(numerics, hash_bits, "bits", 8, 32,
          "width of the alpha-reference hash datapath (docs/numerics.md; run flag --hash-bits overrides it)"),
      I32(numerics, alpha_bits, "bits", 1, 32,
          "fixed-point precision of the fragment opacity (--alpha-bits overrides it)"),
      I32(numerics, surface_id_bits, "bits", 1, 32,
          "width of the per-pixel surface id register, wraps (--surface-id-bits overrides it)"),
  };
  return p;
}

/// Each parameter's basis for its default: a part, a paper, or "assumption"
/// (with what it was chosen against). One entry per parameter (hw_params
/// checks it); generated into docs/config.md and the design files' comments.
struct Basis {
  const char* key;
  const char* basis;
};
constexpr Basis kBasis[] = {
    {"clock.frequency_ghz", "assumption: within current GPUs' core clocks (GeForce RTX 3080: 1.71 GHz boost)"},
    {"source.fragments_per_clock", "assumption: one 2 x 2 quad a clock from the rasterizer"},
    {"source.fifo_depth", "assumption"},
    {"distributor.rop_units", "assumption: one ROP partition per memory channel (dram.channels)"},
    {"distributor.tile_pixels", "assumption: screen tiles of 16 x 16 pixels, two 8 x 8 memory tiles a side"},
    {"distributor.interleave", "assumption: diagonal, so a row or column of tiles spreads over every ROP"},
    {"distributor.fragments_per_clock", "assumption: the source's rate (source.fragments_per_clock)"},
    {"distributor.latency_cycles", "assumption"},
    {"distributor.fifo_depth", "assumption"},
    {"ordering.pixels_in_flight", "assumption"},
    {"ordering.window", "assumption"},
    {"ordering.latency_cycles", "assumption"},
    {"ordering.fifo_depth", "assumption"},
    {"depth_test.samples_per_clock", "assumption: a 16-spp pixel's samples tested in one clock"},
    {"depth_test.latency_cycles", "assumption"},
    {"depth_test.max_outstanding",
     "assumption: enough misses in flight to cover dram.latency_cycles at the unit's rate"},
    {"depth_test.fifo_depth", "assumption"},
    {"tracker.latency_cycles", "paper: Laine & Karras 2011 section 2 (a bitmask and surface-id update per fragment)"},
    {"tracker.fifo_depth", "assumption"},
    {"sorter.kind", "paper: Laine & Karras 2011 section 4 (sort by stored depth); Batcher's bitonic network"},
    {"sorter.fifo_depth", "assumption"},
    {"alpha_ref.lanes", "assumption: one hash per sample of a 16-spp pixel a clock"},
    {"alpha_ref.pipeline_depth", "paper: Laine & Karras 2011 Figure 4 (CalcAlphaRef's hash, one stage a round)"},
    {"alpha_ref.fifo_depth", "assumption"},
    {"writeback.samples_per_clock", "assumption: a 16-spp pixel written in one clock"},
    {"writeback.latency_cycles", "assumption"},
    {"blend.samples_per_clock", "assumption: a 16-spp pixel blended in one clock"},
    {"blend.latency_cycles", "assumption"},
    {"blend.transmittance_format",
     "paper: McGuire & Bavoil 2013 (weighted blended OIT keeps revealage in 8 or 16 bits)"},
    {"blend.accum_format", "paper: McGuire & Bavoil 2013 (RGBA16F accumulation)"},
    {"cache.size_bytes", "assumption: 64 KiB a ROP partition"},
    {"cache.line_bytes", "part: two 32-byte GDDR6 bursts (x16 channel, burst length 16; JEDEC JESD250)"},
    {"cache.ways", "assumption"},
    {"cache.hit_latency_cycles", "assumption"},
    {"cache.fast_clear", "part: current GPUs clear through per-tile state (AMD CMASK / HTILE; Mesa ac_surface.c)"},
    {"dram.channels", "assumption: 4 x 32 B a clock, 192 GB/s at 1.5 GHz, a mid-range GPU's bandwidth"},
    {"dram.bytes_per_clock", "assumption: with dram.channels, 192 GB/s at 1.5 GHz"},
    {"dram.latency_cycles", "assumption: 100 ns at 1.5 GHz, the order of a GPU's DRAM load latency"},
    {"dram.banks", "part: GDDR6, 16 banks a channel (JEDEC JESD250)"},
    {"dram.row_bytes", "part: GDDR6, 2 KiB pages (JEDEC JESD250)"},
    {"dram.row_miss_cycles", "assumption: about tRP + tRCD of GDDR6, 27 ns at 1.5 GHz"},
    {"dram.interleave_bytes", "assumption: 256 B, four lines a channel before the next"},
    {"compression.depth",
     "part: current GPUs compress depth in per-tile plane equations (AMD HTILE, Mesa ac_surface.c; "
     "Hasselgren & Akenine-Moeller 2006); configs/uncompressed.toml turns it off"},
    {"compression.color",
     "part: current GPUs compress MSAA colour per pixel's distinct fragments (AMD FMASK and CMASK, Mesa "
     "radeonsi); configs/uncompressed.toml turns it off"},
    {"compression.tile_pixels", "assumption: 1 KiB of depth at 16 spp, in the range of the references' tiles"},
    {"compression.size_classes",
     "part: AMD delta colour compression stores a 256 B block in 64, 128 or 256 B (Mesa ac_surface.c)"},
    {"compression.depth_planes", "paper: Hasselgren & Akenine-Moeller 2006 (2 to 4 planes a tile)"},
    {"compression.depth_encoder",
     "paper: Hasselgren & Akenine-Moeller 2006 (plane encoding: the rasterizer's planes, no fitting)"},
    {"compression.color_k", "part: AMD FMASK keeps up to 4 fragments a pixel in 4x EQAA and 8x modes (Mesa radeonsi)"},
    {"compression.metadata_cache_bytes",
     "assumption (no public figure): 16 KiB a ROP holds the 2-bit states of the depth and colour tiles of a quarter "
     "of a 1920 x 1080 frame"},
    {"compression.compress_latency_cycles", "assumption (no public figure), small against dram.latency_cycles"},
    {"compression.decompress_latency_cycles", "assumption (no public figure), small against dram.latency_cycles"},
    {"hiz.enable",
     "part: current GPUs keep per-tile depth bounds on chip (AMD HTILE holds a tile's min and max depth, Mesa "
     "ac_surface.c); configs/uncompressed.toml turns it off"},
    {"numerics.hash_bits", "paper: Laine & Karras 2011 Figure 4 (32-bit hash)"},
    {"numerics.alpha_bits", "assumption: a binary32 opacity's precision (docs/numerics.md measures narrower)"},
    {"numerics.surface_id_bits", "paper: Laine & Karras 2011 section 2 (a per-pixel surface id; 32 bits never wraps)"},
};

const char* basis_of(const char* key) {
  const char* found = nullptr;
  for (const Basis& b : kBasis)
    if (std::string(b.key) == key) {
      if (found) throw InternalError(std::string("parameter ") + key + " has two bases");
      found = b.basis;
    }
  if (!found) throw InternalError(std::string("parameter ") + key + " has no basis");
  return found;
}

const Param* find_param(const std::string& key) {
  for (const auto& p : params())
    if (key == p.key) return &p;
  return nullptr;
}

std::string section_of(const std::string& key) { return key.substr(0, key.find('.')); }

[[noreturn]] void fail(const std::string& where, const std::string& key, const std::string& what) {
  throw ConfigError(where + ": " + key + ": " + what);
}
[[noreturn]] void fail_at(const std::string& at, const std::string& what) { throw ConfigError(at + ": " + what); }

std::string real_to_string(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  std::string s(buf, r.ptr);
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";  // n: inf, nan
  return s;
}

std::string value_to_string(const Param& p, HwConfig& c) {
  void* f = p.field(c);
  std::ostringstream os;
  switch (p.kind) {
    case Kind::kU32:
      os << *static_cast<uint32_t*>(f);
      break;
    case Kind::kInt:
      os << *static_cast<int*>(f);
      break;
    case Kind::kReal:
      os << real_to_string(*static_cast<double*>(f));
      break;
    case Kind::kBool:
      os << (*static_cast<bool*>(f) ? "true" : "false");
      break;
    case Kind::kSorter:
      os << '"' << to_string(*static_cast<SorterKind*>(f)) << '"';
      break;
    case Kind::kInterleave:
      os << '"' << to_string(*static_cast<Interleave*>(f)) << '"';
      break;
    case Kind::kDepthEncoder:
      os << '"' << to_string(*static_cast<DepthEncoder*>(f)) << '"';
      break;
    case Kind::kTransFormat:
    case Kind::kAccumFormat:
      os << '"' << to_string(*static_cast<TargetFormat*>(f)) << '"';
      break;
  }
  return os.str();
}

/// A whole number as an integer (1073741824), else the fewest digits that
/// read back as v (0.01, 1e+30).
namespace {
std::string shortest(double v) {
  if (v == std::floor(v) && std::fabs(v) < 1e15) return std::to_string(int64_t(v));
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}
}  // namespace

std::string range_of(const Param& p) {
  std::ostringstream os;
  switch (p.kind) {
    case Kind::kU32:
    case Kind::kInt:
    case Kind::kReal:
      os << shortest(p.lo) << " .. " << shortest(p.hi) << (p.pow2 ? ", power of two" : "");
      break;
    case Kind::kBool:
      os << "true, false";
      break;
    case Kind::kSorter:
      os << "bitonic, rank, serial";
      break;
    case Kind::kInterleave:
      os << "diagonal, row";
      break;
    case Kind::kDepthEncoder:
      os << "plane, fit";
      break;
    case Kind::kTransFormat:
    case Kind::kAccumFormat: {
      const char* sep = "";
      for (TargetFormat f : formats_of(p.kind)) {
        os << sep << to_string(f);
        sep = ", ";
      }
      break;
    }
  }
  return os.str();
}

void set_u32(const Param& p, HwConfig& c, int64_t v, const std::string& at) {
  if (double(v) < p.lo || double(v) > p.hi)
    fail_at(at, "value " + std::to_string(v) + " out of range (" + range_of(p) + ")");
  if (p.pow2 && !is_pow2(uint64_t(v))) fail_at(at, "value " + std::to_string(v) + " is not a power of two");
  if (p.kind == Kind::kInt)
    *static_cast<int*>(p.field(c)) = int(v);
  else
    *static_cast<uint32_t*>(p.field(c)) = uint32_t(v);
}
void set_real(const Param& p, HwConfig& c, double v, const std::string& at) {
  if (!std::isfinite(v) || v < p.lo || v > p.hi) fail_at(at, "value out of range (" + range_of(p) + ")");
  *static_cast<double*>(p.field(c)) = v;
}
void set_name(const Param& p, HwConfig& c, const std::string& s, const std::string& at) {
  if (p.kind == Kind::kTransFormat || p.kind == Kind::kAccumFormat) {
    for (TargetFormat f : formats_of(p.kind))
      if (s == to_string(f)) {
        *static_cast<TargetFormat*>(p.field(c)) = f;
        return;
      }
  } else if (p.kind == Kind::kSorter) {
    for (SorterKind k : {SorterKind::kBitonic, SorterKind::kRank, SorterKind::kSerial})
      if (s == to_string(k)) {
        *static_cast<SorterKind*>(p.field(c)) = k;
        return;
      }
  } else if (p.kind == Kind::kDepthEncoder) {
    for (DepthEncoder k : {DepthEncoder::kPlane, DepthEncoder::kFit})
      if (s == to_string(k)) {
        *static_cast<DepthEncoder*>(p.field(c)) = k;
        return;
      }
  } else {
    for (Interleave k : {Interleave::kDiagonal, Interleave::kRow})
      if (s == to_string(k)) {
        *static_cast<Interleave*>(p.field(c)) = k;
        return;
      }
  }
  fail_at(at, "\"" + s + "\" is not one of " + range_of(p));
}

}  // namespace hw_detail

using namespace hw_detail;

const std::vector<ParamInfo>& hw_params() {
  static const std::vector<ParamInfo> v = [] {
    std::vector<ParamInfo> r;
    HwConfig def;
    for (const auto& p : params())
      r.push_back({p.key, p.unit, p.meaning, range_of(p), value_to_string(p, def), basis_of(p.key)});
    if (r.size() != std::size(kBasis)) throw InternalError("a basis names no parameter");
    return r;
  }();
  return v;
}

std::string hw_params_markdown() {
  std::ostringstream os;
  os << "| key | unit | default | range | meaning | basis of the default |\n|---|---|---|---|---|---|\n";
  for (const auto& p : hw_params())
    os << "| `" << p.key << "` | " << p.unit << " | " << p.default_value << " | " << p.range << " | " << p.meaning
       << " | " << p.basis << " |\n";
  return os.str();
}

}  // namespace ropsim
