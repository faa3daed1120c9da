// The payload's fields (docs/livepoints.md "The file"), each record's writer
// beside its reader, so that a field changes in both at once; decode checks
// every count, mask and position as it reads. One format, one file.
#include "sim/fidelity/sampled/livepoint_payload.h"

#include <xxhash.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <memory>
#include <string_view>

#include "rtl_models/algo/bits.h"
#include "rtl_models/algo/half.h"
#include "traces/format/utf8.h"
#include "util/byte_codec.h"
#include "util/errors.h"
#include "util/memory_budget.h"
#include "util/output_file.h"

namespace ropsim {

namespace {

// Arrays of integers and floats are copied as they are in memory.
static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "the library format is little-endian");

/// The most fragments one drawing of an input holds: a trace's header
/// count field is 48 bits (the count + 1).
constexpr uint64_t kMaxInputFragments = (uint64_t{1} << 48) - 2;
/// A byte counter counts at most this many bytes per fragment: 16 per sample
/// (a blend target's RGBA32F) and a slab pixel's 16 layers (16 (4 + 6 + 8) + 1).
constexpr uint64_t kMaxCounterBytesPerSample = 16, kMaxCounterBytesPerFragment = 289;

/// A mask with no bit at or above `bits`.
bool within(uint64_t mask, int bits) { return bits >= 64 || (mask >> bits) == 0; }

/// Reads the payload back; every read is bounds-checked and a failure names
/// the library and what was being read.
class Get {
 public:
  Get(const std::vector<uint8_t>& b, const std::string& path) : b_(b), path_(path) {}
  void at(std::string what) { what_ = std::move(what); }
  uint8_t u8() { return *take(1); }
  uint16_t u16() { return get_u16(take(2)); }
  uint32_t u32() { return get_u32(take(4)); }
  uint64_t u64() { return get_u64(take(8)); }
  float f32() { return get_f32(take(4)); }
  bool flag() {
    const uint8_t v = u8();
    if (v > 1) fail("a flag is " + std::to_string(v));
    return v != 0;
  }
  /// A count of items of at least item_bytes bytes each, checked against what is left.
  uint64_t count(uint64_t item_bytes) {
    const uint64_t n = u64();
    if (n > kMaxLivePointCount || n * std::max<uint64_t>(item_bytes, 1) > b_.size() - pos_)
      fail("a count of " + std::to_string(n) + " runs past the payload's end");
    return n;
  }
  std::string str() {
    const uint64_t n = count(1);
    std::string s(reinterpret_cast<const char*>(b_.data() + pos_), size_t(n));
    pos_ += size_t(n);
    return s;
  }
  template <class T>
  void array(T* v, size_t n) {
    if ((b_.size() - pos_) / sizeof(T) < n) fail("the payload ends");
    std::memcpy(v, b_.data() + pos_, n * sizeof(T));
    pos_ += n * sizeof(T);
  }
  bool done() const { return pos_ == b_.size(); }
  [[noreturn]] void fail(const std::string& why) const {
    throw UserError(path_ + ": not a valid live-point library (" + what_ + " at payload byte " + std::to_string(pos_) +
                    ": " + why + ")");
  }

 private:
  /// The next n bytes, once they are known to be there.
  const uint8_t* take(size_t n) {
    if (b_.size() - pos_ < n) fail("the payload ends");
    const uint8_t* p = b_.data() + pos_;
    pos_ += n;
    return p;
  }
  const std::vector<uint8_t>& b_;
  const std::string& path_;
  size_t pos_ = 0;
  std::string what_ = "the header";
};

void put_header(PayloadWriter& p, const TraceHeader& h) {
  p.u32(h.width);
  p.u32(h.height);
  p.u32(uint32_t(h.spp));
  p.u8(uint8_t(h.depth_mode));
  p.u8(uint8_t(h.color_format));
  p.u8(uint8_t(h.compression));
  for (float c : h.clear_color) p.f32(c);
  p.f32(h.clear_depth);
  for (const SamplePos& s : h.positions) {
    p.u8(s.x);
    p.u8(s.y);
  }
  p.str(h.scene_name);
  p.u8(h.checksummed);
  // The draw table (trace format version 2), in draw-id order.
  p.u64(h.draws.size());
  for (const DrawState& s : h.draws.states()) {
    p.u32(s.draw_id);
    p.u8(s.blend);
    p.u8(s.depth_test);
    p.u8(s.depth_write);
    for (uint8_t v :
         {uint8_t(s.eq_rgb), uint8_t(s.eq_alpha), uint8_t(s.src_rgb), uint8_t(s.dst_rgb), uint8_t(s.src_alpha),
          uint8_t(s.dst_alpha), uint8_t(s.depth_func), s.color_mask, uint8_t(s.encoding)})
      p.u8(v);
    for (float c : s.blend_color) p.f32(c);
    p.str(s.name);
  }
}

/// A draw state's bytes in the payload before its name's.
constexpr uint64_t kDrawStateBytes = 4 + 3 + 9 + 16 + 8;

TraceHeader get_header(Get& g) {
  TraceHeader h;
  h.width = g.u32();
  h.height = g.u32();
  h.spp = int(g.u32());
  h.depth_mode = DepthMode(g.u8());
  h.color_format = ColorFormat(g.u8());
  h.compression = Compression(g.u8());
  for (float& c : h.clear_color) c = g.f32();
  h.clear_depth = g.f32();
  for (SamplePos& s : h.positions) {
    s.x = g.u8();
    s.y = g.u8();
  }
  h.scene_name = g.str();
  h.checksummed = g.flag();
  const uint64_t n_draws = g.count(kDrawStateBytes);
  std::vector<DrawState> states(static_cast<size_t>(n_draws));
  for (DrawState& s : states) {
    s.draw_id = g.u32();
    s.blend = g.flag();
    s.depth_test = g.flag();
    s.depth_write = g.flag();
    s.eq_rgb = BlendEquation(g.u8());
    s.eq_alpha = BlendEquation(g.u8());
    s.src_rgb = BlendFactor(g.u8());
    s.dst_rgb = BlendFactor(g.u8());
    s.src_alpha = BlendFactor(g.u8());
    s.dst_alpha = BlendFactor(g.u8());
    s.depth_func = DepthFunc(g.u8());
    s.color_mask = g.u8();
    s.encoding = TargetEncoding(g.u8());
    for (float& c : s.blend_color) c = g.f32();
    s.name = g.str();
    if (&s != states.data() && s.draw_id <= (&s - 1)->draw_id)
      g.fail("the trace header: the draw states are not in increasing draw-id order");
  }
  h.draws = DrawTable(std::move(states));
  const std::string why = validate_header(h);  // the draw table's fields included
  if (!why.empty()) g.fail("the trace header: " + why);
  if (!is_valid_utf8(h.scene_name)) g.fail("the trace header: scene name is not valid UTF-8");
  return h;
}

void put_fragment(PayloadWriter& p, const TraceHeader& h, const Fragment& f) {
  p.u32(f.draw_id);
  p.u32(f.prim_id);
  p.u16(f.x);
  p.u16(f.y);
  p.u64(f.coverage);
  p.f32(f.z0);
  p.f32(f.dzdx);
  p.f32(f.dzdy);
  if (h.depth_mode == DepthMode::kPerSample)
    for (int i = 0; i < h.spp; ++i) p.f32(f.z[size_t(i)]);
  for (float c : f.rgb) p.f32(c);
  p.f32(f.alpha);
}

Fragment get_fragment(Get& g, const TraceHeader& h) {
  Fragment f;
  f.draw_id = g.u32();
  f.prim_id = g.u32();
  f.x = g.u16();
  f.y = g.u16();
  f.coverage = g.u64();
  f.z0 = g.f32();
  f.dzdx = g.f32();
  f.dzdy = g.f32();
  if (h.depth_mode == DepthMode::kPerSample)
    for (int i = 0; i < h.spp; ++i) f.z[size_t(i)] = g.f32();
  for (float& c : f.rgb) c = g.f32();
  f.alpha = g.f32();
  const std::string why = validate_fragment(h, f);
  if (!why.empty()) g.fail("a fragment: " + why);
  return f;
}

void put_method(PayloadWriter& p, const MethodConfig& m) {
  p.str(to_string(m.method));
  p.u32(uint32_t(m.numerics.hash_bits));
  p.u32(uint32_t(m.numerics.alpha_bits));
  p.u32(uint32_t(m.numerics.surface_id_bits));
  p.u64(m.seed);
  p.u32(uint32_t(m.slab_layers));
  p.u32(uint32_t(m.slab_bits));
  p.u8(uint8_t(m.formats.transmittance));
  p.u8(uint8_t(m.formats.accum));
  p.u8(uint8_t(m.enderton_selection));
}

MethodConfig get_method(Get& g) {
  MethodConfig m;
  const std::string name = g.str();
  if (!parse_method(name, m.method)) g.fail("unknown method \"" + name + "\"");
  m.numerics.hash_bits = int(g.u32());
  m.numerics.alpha_bits = int(g.u32());
  m.numerics.surface_id_bits = int(g.u32());
  if (const char* why = validate(m.numerics)) g.fail(why);
  m.seed = g.u64();
  m.slab_layers = int(g.u32());
  m.slab_bits = int(g.u32());
  const uint8_t tf = g.u8(), af = g.u8(), es = g.u8();
  if (tf > uint8_t(TargetFormat::kRGBA32F) || af > uint8_t(TargetFormat::kRGBA32F) ||
      es > uint8_t(EndertonSelection::kOriginal))
    g.fail("a format or selection out of range");
  m.formats.transmittance = TargetFormat(tf);
  m.formats.accum = TargetFormat(af);
  m.enderton_selection = EndertonSelection(es);
  // k and b as --slab-layers and --slab-bits take them (for every method, as the CLI checks them).
  if (m.slab_layers < 1 || m.slab_layers > kMaxSlabLayers)
    g.fail("SLAB layers k " + std::to_string(m.slab_layers) + " is not in [1, " + std::to_string(kMaxSlabLayers) + "]");
  if (m.slab_bits < 1 || m.slab_bits > 64) g.fail("SLAB bits b " + std::to_string(m.slab_bits) + " is not in [1, 64]");
  // What record_livepoints records: one pass, no blend targets, not the reference.
  if (m.method == Method::kReference || passes_of(m.method).count != 1 || has_blend_pass(m.method))
    g.fail(std::string("method ") + to_string(m.method) + " has no live-points (several passes or blend targets)");
  return m;
}

/// A stored sample's bytes in a pre-state or tile pixel: depth (binary32),
/// colour (3 x binary16) and plane key (64 bits).
constexpr size_t kSampleBytes = 4 + 6 + 8;

void put_pre(PayloadWriter& p, const PrePixels& pre, int spp) {
  p.u8(pre.tracker);
  p.u32(uint32_t(pre.slab_bits));
  p.u64(pre.size());
  for (size_t i = 0; i < pre.size(); ++i) {
    p.u16(pre.x[i]);
    p.u16(pre.y[i]);
    p.array(&pre.depth[i * size_t(spp)], size_t(spp));
    p.array(&pre.rgb[3 * i * size_t(spp)], 3 * size_t(spp));
    p.array(&pre.planes[i * size_t(spp)], size_t(spp));
    if (pre.tracker) {
      p.u64(pre.trackers[i].covered);
      p.u32(pre.trackers[i].surface_id);
    }
    if (pre.slab_bits > 0) {
      const SlabPixel& sp = pre.slabs[i];
      p.u8(sp.count);
      for (int l = 0; l < sp.count; ++l) {
        p.f32(sp.depth[l]);
        p.u64(sp.mask[l]);
        for (int c = 0; c < 3; ++c) p.u16(sp.rgb[l][c]);
      }
    }
  }
}

/// Checks a depth the store can hold: the clear depth or a canonical one, in [0, 1].
void check_depth(Get& g, float z, const char* what) {
  if (!(z >= 0.0f && z <= 1.0f)) g.fail(std::string(what) + " is not in [0, 1]");
}

/// Live-point kk's tile pixels (TilePixels): each a resident pixel with
/// written samples that the pre-state does not hold, in (y, x) order, its
/// depths in [0, 1]. Refused naming the record.
void get_tile_pixels(Get& g, LivePoint& lp, const TraceHeader& h, size_t kk, BudgetShare& mem,
                     const std::string& what) {
  g.at("live-point " + std::to_string(kk) + "'s tile pixels");
  const size_t spp = size_t(h.spp);
  const uint64_t n = g.count(4 + kSampleBytes * spp);
  if (n > lp.resident.size()) g.fail("more tile pixels than the live-point's resident pixels");
  mem.add(n * (4 + kSampleBytes * spp), what);
  TilePixels& tp = lp.tiles;
  tp.x.resize(size_t(n));
  tp.y.resize(size_t(n));
  tp.depth.resize(size_t(n) * spp);
  tp.rgb.resize(3 * size_t(n) * spp);
  tp.planes.resize(size_t(n) * spp);
  // The resident pixels with written samples, by (y, x), to find each in.
  std::vector<uint64_t> written;
  for (const Resident& r : lp.resident)
    if (r.written) written.push_back(uint64_t(r.y) << 16 | r.x);
  std::sort(written.begin(), written.end());
  size_t pre_at = 0;
  uint64_t prev = 0;
  for (size_t i = 0; i < size_t(n); ++i) {
    tp.x[i] = g.u16();
    tp.y[i] = g.u16();
    const uint64_t key = uint64_t(tp.y[i]) << 16 | tp.x[i];
    if (tp.x[i] >= h.width || tp.y[i] >= h.height || (i > 0 && key <= prev))
      g.fail("tile pixel (" + std::to_string(tp.x[i]) + ", " + std::to_string(tp.y[i]) +
             ") off the screen or out of (y, x) order");
    prev = key;
    if (!std::binary_search(written.begin(), written.end(), key))
      g.fail("tile pixel (" + std::to_string(tp.x[i]) + ", " + std::to_string(tp.y[i]) +
             ") is not a resident pixel with written samples");
    while (pre_at < lp.pre.size() && (uint64_t(lp.pre.y[pre_at]) << 16 | lp.pre.x[pre_at]) < key) ++pre_at;
    if (pre_at < lp.pre.size() && (uint64_t(lp.pre.y[pre_at]) << 16 | lp.pre.x[pre_at]) == key)
      g.fail("tile pixel (" + std::to_string(tp.x[i]) + ", " + std::to_string(tp.y[i]) + ") is a pre-state pixel too");
    g.array(&tp.depth[i * spp], spp);
    for (size_t j = 0; j < spp; ++j) check_depth(g, tp.depth[i * spp + j], "a tile pixel's depth");
    g.array(&tp.rgb[3 * i * spp], 3 * spp);
    g.array(&tp.planes[i * spp], spp);  // any value: keys are only compared
  }
}

void get_pre(Get& g, PrePixels& pre, const TraceHeader& h, const MethodConfig& m, uint64_t fragments, BudgetShare& mem,
             const std::string& what) {
  const size_t spp = size_t(h.spp);
  pre.tracker = g.flag();
  pre.slab_bits = int(g.u32());
  if (pre.tracker != traits(m.method).tracker)  // as FunctionalRop sets its store up
    g.fail(std::string("the tracker flag is not method ") + to_string(m.method) + "'s");
  if (pre.slab_bits != (m.method == Method::kSlab ? m.slab_bits : 0))
    g.fail("SLAB bits " + std::to_string(pre.slab_bits) + " are not the method's");
  const uint64_t n = g.count(4 + kSampleBytes * spp);
  if (n > fragments) g.fail("more pre-state pixels than the live-point's fragments touch");
  mem.add(
      n * (4 + kSampleBytes * spp + (pre.tracker ? sizeof(TrackerState) : 0) + (pre.slab_bits ? sizeof(SlabPixel) : 0)),
      what);
  pre.x.resize(size_t(n));
  pre.y.resize(size_t(n));
  pre.depth.resize(size_t(n) * spp);
  pre.rgb.resize(3 * size_t(n) * spp);
  pre.planes.resize(size_t(n) * spp);
  if (pre.tracker) pre.trackers.resize(size_t(n));
  if (pre.slab_bits > 0) pre.slabs.resize(size_t(n));
  uint64_t prev = 0;
  for (size_t i = 0; i < size_t(n); ++i) {
    pre.x[i] = g.u16();
    pre.y[i] = g.u16();
    const uint64_t key = uint64_t(pre.y[i]) << 16 | pre.x[i];
    if (pre.x[i] >= h.width || pre.y[i] >= h.height || (i > 0 && key <= prev))
      g.fail("a pre-state pixel off the screen or out of order");
    prev = key;
    g.array(&pre.depth[i * spp], spp);
    for (size_t j = 0; j < spp; ++j) check_depth(g, pre.depth[i * spp + j], "a pre-state sample's depth");
    g.array(&pre.rgb[3 * i * spp], 3 * spp);
    g.array(&pre.planes[i * spp], spp);  // any value: keys are only compared
    if (pre.tracker) {
      pre.trackers[i].covered = g.u64();
      pre.trackers[i].surface_id = g.u32();
      if (!within(pre.trackers[i].covered, h.spp)) g.fail("a pre-state tracker covers samples past spp");
    }
    if (pre.slab_bits > 0) {
      SlabPixel& sp = pre.slabs[i];
      sp.count = g.u8();
      if (sp.count > m.slab_layers)
        g.fail("a slab pixel with " + std::to_string(sp.count) +
               " layers, more than k = " + std::to_string(m.slab_layers));
      for (int l = 0; l < sp.count; ++l) {
        sp.depth[l] = g.f32();
        sp.mask[l] = g.u64();
        for (int c = 0; c < 3; ++c) sp.rgb[l][c] = g.u16();
        check_depth(g, sp.depth[l], "a slab layer's depth");
        if (!within(sp.mask[l], pre.slab_bits)) g.fail("a slab layer's mask has bits past b");
      }
    }
  }
}

void put_touch(PayloadWriter& p, const Touch& t) {
  p.u64(t.covered);
  p.u64(t.written);
  p.u16(t.x);
  p.u16(t.y);
  p.u8(uint8_t(t.reached_write) | uint8_t(t.slab_kept) << 1 | uint8_t(t.routed) << 2 | uint8_t(t.reads_colour) << 3 |
       uint8_t(t.depth_write) << 4);
}

Touch get_touch(Get& g) {
  Touch t;
  t.covered = g.u64();
  t.written = g.u64();
  t.x = g.u16();
  t.y = g.u16();
  const uint8_t fl = g.u8();
  // Bits: reached the write, slab kept, routed, reads colour, writes depth
  // (the last two only for a routed draw).
  if (fl > 31 || (!(fl & 4) && (fl & 24))) g.fail("a touch's flags are " + std::to_string(fl));
  t.reached_write = fl & 1;
  t.slab_kept = fl & 2;
  t.routed = fl & 4;
  t.reads_colour = fl & 8;
  t.depth_write = fl & 16;
  return t;
}

void put_image(PayloadWriter& p, const Image& img) {
  p.u32(img.width);
  p.u32(img.height);
  for (float c : img.background()) p.f32(c);
  // The rows holding a written pixel, each whole.
  std::vector<float> row(size_t(img.width) * 3);
  uint64_t rows = 0;
  for (uint32_t y = 0; y < img.height; ++y) rows += !img.row_untouched(y);
  p.u64(rows);
  for (uint32_t y = 0; y < img.height; ++y) {
    if (img.row_untouched(y)) continue;
    p.u32(y);
    img.row(y, row.data());
    for (float c : row) p.f32(c);
  }
}

Image get_image(Get& g, const TraceHeader& h) {
  const uint32_t w = g.u32(), ht = g.u32();
  if (w != h.width || ht != h.height) g.fail("the image's size is not the screen's");
  std::array<float, 3> bg;
  for (float& c : bg) c = g.f32();
  // The background is the clear colour as the store holds it (binary16).
  for (int c = 0; c < 3; ++c) {
    const float want = half_to_float(float_to_half(h.clear_color[size_t(c)]));
    if (std::memcmp(&bg[size_t(c)], &want, sizeof want) != 0) g.fail("the background is not the clear colour");
  }
  // A pixel is a resolve of binary16 samples: in [0, 65504], or +inf where
  // a sample can overflow binary16 (an rgb-f32 colour, a clear colour of
  // 65520 or more). Never NaN, never negative.
  const bool may_overflow =
      h.color_format == ColorFormat::kRgbF32 || std::isinf(bg[0]) || std::isinf(bg[1]) || std::isinf(bg[2]);
  Image img(w, ht, bg);
  const uint64_t rows = g.count(4 + uint64_t(w) * 12);
  if (rows > ht) g.fail(std::to_string(rows) + " written rows, more than the image's " + std::to_string(ht));
  int64_t prev = -1;
  for (uint64_t r = 0; r < rows; ++r) {
    const uint32_t y = g.u32();
    if (y >= ht) g.fail("an image row off the screen");
    if (int64_t(y) <= prev) g.fail("image row " + std::to_string(y) + " out of order or given twice");
    prev = y;
    for (uint32_t x = 0; x < w; ++x) {
      float c[3];
      for (float& v : c) {
        v = g.f32();
        if (!(v >= 0.0f && (v <= 65504.0f || (may_overflow && std::isinf(v)))))
          g.fail("pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") holds " + std::to_string(v) +
                 ", not a resolved binary16 value");
      }
      // Only pixels other than the background take a tile, as in the resolve.
      if (std::memcmp(c, bg.data(), sizeof c) != 0) std::memcpy(img.at(x, y), c, sizeof c);
    }
  }
  return img;
}

/// The sampling parameters as record_livepoints leaves them, over N fragments.
void check_sampling(Get& g, const LivePoints& lib) {
  const SamplingParams& s = lib.params;
  const uint64_t n = lib.fragments, max_n = kMaxInputFragments * lib.input.spec.repeat;
  auto bad = [&](const std::string& why) { g.fail(why); };
  if (n > max_n)
    bad("N " + std::to_string(n) + " fragments, more than an input can hold (" + std::to_string(max_n) + ": 2^48 - 2 " +
        "per drawing)");
  if (lib.whole) {
    if (s.units != 1 || s.unit_fragments != n || s.warmup_fragments != 0 || s.cooldown_fragments != 0)
      bad("a whole-input library must have K = 1, U = N, W = 0 and C = 0 (K " + std::to_string(s.units) + ", U " +
          std::to_string(s.unit_fragments) + ", W " + std::to_string(s.warmup_fragments) + ", C " +
          std::to_string(s.cooldown_fragments) + ", N " + std::to_string(n) + ")");
    return;
  }
  if (s.units < 1 || s.units > n)
    bad("K " + std::to_string(s.units) + " units is not in [1, N = " + std::to_string(n) + "]");
  const uint64_t period = n / s.units;
  if (s.unit_fragments < 1 || s.unit_fragments > period)
    bad("U " + std::to_string(s.unit_fragments) + " fragments is not in [1, N / K = " + std::to_string(period) + "]");
  if (s.cooldown_fragments > period - s.unit_fragments)
    bad("C " + std::to_string(s.cooldown_fragments) +
        " fragments is more than N / K - U = " + std::to_string(period - s.unit_fragments));
}

/// Every counter within what N fragments of the header's spp can produce.
void check_counters(Get& g, const LivePoints& lib) {
  const uint64_t n = lib.fragments, spp = uint64_t(lib.header.spp);
  if (lib.counters.fragments != n)
    g.fail("fragments " + std::to_string(lib.counters.fragments) + " is not N = " + std::to_string(n));
  // SLAB counts the mask bits of its layers (b of them) as samples.
  const uint64_t per_sample =
      std::max<uint64_t>(spp, lib.method.method == Method::kSlab ? uint64_t(lib.method.slab_bits) : 0);
  const uint64_t tiles = uint64_t(ceil_div(lib.header.width, 8u)) * ceil_div(lib.header.height, 8u);
  const std::vector<StatDesc>& descs = counter_descs();
  size_t i = 0;
  lib.counters.for_each([&](const char* name, uint64_t v) {
    const std::string unit = descs[i++].unit;
    unsigned __int128 most = n;  // fragments, events
    if (unit == "samples") most = (unsigned __int128)n * per_sample;
    if (unit == "bytes") most = (unsigned __int128)n * (kMaxCounterBytesPerSample * spp + kMaxCounterBytesPerFragment);
    if (unit == "tiles") most = tiles;
    if (v > most)
      g.fail(std::string(name) + " " + std::to_string(v) + " " + unit + " is more than " + std::to_string(n) +
             " fragments at " + std::to_string(spp) + " spp can produce");
  });
}

}  // namespace

void encode_livepoint_payload(const LivePoints& lib, PayloadWriter& p) {
  const TraceHeader& h = lib.header;
  const InputSpec& in = lib.input.spec;
  p.str(in.trace_path);
  p.str(in.scene.name);
  p.u32(uint32_t(in.scene.spp));
  p.u32(in.scene.width);
  p.u32(in.scene.height);
  p.u64(in.scene.seed);
  p.u32(in.repeat);
  p.str(lib.input.description);
  p.u8(lib.input.from_trace);
  p.u64(lib.input.digest);
  put_header(p, h);
  put_method(p, lib.method);
  const SamplingParams& s = lib.params;
  for (uint64_t v : {s.unit_fragments, s.warmup_fragments, s.cooldown_fragments, s.units, s.warming_fragments})
    p.u64(v);
  p.array(&s.warming_reach, 1);
  p.u8(lib.whole);
  p.u64(lib.fragments);
  // The counters by name, so a reader of another build refuses a mismatch.
  uint64_t n_counters = 0;
  lib.counters.for_each([&](const char*, uint64_t) { ++n_counters; });
  p.u64(n_counters);
  lib.counters.for_each([&](const char* name, uint64_t v) {
    p.str(name);
    p.u64(v);
  });
  put_image(p, lib.image);
  p.u64(lib.points.size());
  for (const LivePoint& lp : lib.points) {
    p.u64(lp.first);
    p.u64(lp.warmup);
    p.u64(lp.window);
    p.u64(lp.fragments.size());
    for (const Fragment& f : lp.fragments) {
      put_fragment(p, h, f);
      p.piece();
    }
    put_pre(p, lp.pre, h.spp);
    p.piece();
    p.u64(lp.resident.size());
    for (const Resident& r : lp.resident) {
      p.u64(r.written);
      p.u16(r.x);
      p.u16(r.y);
      p.u8(uint8_t(r.tracker) | uint8_t(r.layers) << 1);
    }
    p.u64(lp.tiles.size());
    for (size_t i = 0; i < lp.tiles.size(); ++i) {
      p.u16(lp.tiles.x[i]);
      p.u16(lp.tiles.y[i]);
      p.array(&lp.tiles.depth[i * size_t(h.spp)], size_t(h.spp));
      p.array(&lp.tiles.rgb[3 * i * size_t(h.spp)], 3 * size_t(h.spp));
      p.array(&lp.tiles.planes[i * size_t(h.spp)], size_t(h.spp));
      p.piece();
    }
    p.u64(lp.warming.size());
    for (const Touch& t : lp.warming) {
      put_touch(p, t);
      p.piece();
    }
  }
  p.flush();
}

LivePoints decode_livepoint_payload(const std::vector<uint8_t>& bytes, const std::string& path) {
  Get g(bytes, path);
  LivePoints lib;
  g.at("the input");
  InputSpec& in = lib.input.spec;
  in.trace_path = g.str();
  in.scene.name = g.str();
  in.scene.spp = int(g.u32());
  in.scene.width = g.u32();
  in.scene.height = g.u32();
  in.scene.seed = g.u64();
  in.repeat = g.u32();
  lib.input.description = g.str();
  lib.input.from_trace = g.flag();
  lib.input.digest = g.u64();
  if (in.repeat < 1 || in.repeat > kMaxRepeat)
    g.fail("repeat " + std::to_string(in.repeat) + " is not in [1, " + std::to_string(kMaxRepeat) + "]");
  if (lib.input.from_trace != in.from_trace()) g.fail("the from-trace flag is not the input's");
  if (!in.from_trace() && (!is_valid_spp(in.scene.spp) || in.scene.width > kMaxScreenSide ||
                           in.scene.height > kMaxScreenSide || in.scene.name.empty()))
    g.fail("the scene's name, spp or screen is out of range");
  if (lib.input.description != in.describe()) g.fail("the description is not the input's");
  g.at("the trace header");
  lib.header = get_header(g);
  const TraceHeader& h = lib.header;
  if (!in.from_trace() && (h.spp != in.scene.spp || (in.scene.width && in.scene.width != h.width) ||
                           (in.scene.height && in.scene.height != h.height)))
    g.fail("the screen or spp is not the scene's");
  g.at("the method");
  lib.method = get_method(g);
  g.at("the sampling parameters");
  SamplingParams& s = lib.params;
  for (uint64_t* v : {&s.unit_fragments, &s.warmup_fragments, &s.cooldown_fragments, &s.units, &s.warming_fragments})
    *v = g.u64();
  g.array(&s.warming_reach, 1);
  if (!(s.warming_reach >= 0 && s.warming_reach <= 1e6)) g.fail("the warming reach is out of range");
  lib.whole = g.flag();
  lib.fragments = g.u64();
  check_sampling(g, lib);
  g.at("the counters");
  uint64_t n_counters = 0;
  lib.counters.for_each([&](const char*, uint64_t) { ++n_counters; });
  if (g.u64() != n_counters) g.fail("another build's counters");
  // Counters::for_each is const; write through a name-ordered walk.
  std::vector<uint64_t> values;
  std::vector<std::string> names;
  lib.counters.for_each([&](const char* name, uint64_t) { names.emplace_back(name); });
  for (const std::string& name : names) {
    if (g.str() != name) g.fail("another build's counters (expected " + name + ")");
    values.push_back(g.u64());
  }
  {
    size_t i = 0;
#define ROPSIM_X(name, unit, meaning, scope) lib.counters.name = values[i++];
    ROPSIM_COUNTERS(ROPSIM_X)
#undef ROPSIM_X
  }
  check_counters(g, lib);
  g.at("the image");
  lib.image = get_image(g, h);
  g.at("the live-points");
  const uint64_t k = g.count(8);
  if (k != lib.params.units) g.fail("the unit count is not the sampling parameters'");
  // Each point's vectors are charged before they are allocated (the payload's
  // bytes bound them, but a fragment takes more memory than its bytes).
  const std::string what = path + ": the live-point library's points";
  lib.mem.add(k * sizeof(LivePoint), what);
  lib.points.resize(size_t(k));
  uint64_t prev_end = 0;
  for (size_t kk = 0; kk < lib.points.size(); ++kk) {
    LivePoint& lp = lib.points[kk];
    lp.first = g.u64();
    lp.warmup = g.u64();
    lp.window = g.u64();
    const uint64_t n = g.count(36);
    // Where the recording placed unit kk (the sampling parameters are in range).
    const UnitSpan span = unit_span(lib.fragments, lib.params, kk, prev_end);
    if (lp.first != span.first || lp.warmup != span.start - span.first || lp.window != lib.params.unit_fragments ||
        n != span.end - span.first)
      g.fail("live-point " + std::to_string(kk) + " (fragments " + std::to_string(lp.first) + " + " +
             std::to_string(n) + ", warm-up " + std::to_string(lp.warmup) + ", window " + std::to_string(lp.window) +
             ") is not where the sampling parameters place it (fragments " + std::to_string(span.first) + " + " +
             std::to_string(span.end - span.first) + ", warm-up " + std::to_string(span.start - span.first) + ")");
    prev_end = span.end;
    lib.mem.add(n * sizeof(Fragment), what);
    lp.fragments.reserve(size_t(n));
    for (uint64_t i = 0; i < n; ++i) lp.fragments.push_back(get_fragment(g, h));
    get_pre(g, lp.pre, h, lib.method, n, lib.mem, what);
    const uint64_t res = g.count(13);
    lib.mem.add(res * sizeof(Resident), what);
    lp.resident.resize(size_t(res));
    for (Resident& r : lp.resident) {
      r.written = g.u64();
      r.x = g.u16();
      r.y = g.u16();
      const uint8_t fl = g.u8();
      if (fl > 3 || r.x >= h.width || r.y >= h.height || !within(r.written, h.spp)) g.fail("a resident pixel");
      r.tracker = fl & 1;
      r.layers = fl & 2;
    }
    get_tile_pixels(g, lp, h, kk, lib.mem, what);
    g.at("the live-points");
    const uint64_t t = g.count(21);
    if (t > lib.params.warming_fragments || t > lp.first)
      g.fail(std::to_string(t) + " warming touches, more than T or the fragments before the live-point");
    lib.mem.add(t * sizeof(Touch), what);
    lp.warming.resize(size_t(t));
    for (Touch& x : lp.warming) {
      x = get_touch(g);
      if (x.x >= h.width || x.y >= h.height) g.fail("a touch off the screen");
      if (!within(x.covered, h.spp) || !within(x.written, h.spp)) g.fail("a touch's samples past spp");
    }
  }
  if (!g.done()) g.fail("bytes after the last live-point");
  return lib;
}

void canonicalise(const TraceHeader& h, Fragment& f) {
  if (h.depth_mode != DepthMode::kPerSample) {
    f.z.fill(0.0f);
    return;
  }
  // A per-sample record carries the covered samples' depths only: whatever
  // the reader's slot held before stands in the others.
  for (size_t i = 0; i < f.z.size(); ++i)
    if (!(i < size_t(h.spp) && (f.coverage >> i & 1))) f.z[i] = 0.0f;
}

InputIdentity input_identity(const InputSpec& in) {
  InputIdentity id;
  id.spec = in;
  id.description = in.describe();
  id.from_trace = in.from_trace();
  XXH3_state_t* st = XXH3_createState();
  invariant(st != nullptr, "XXH3 state allocated");
  std::unique_ptr<XXH3_state_t, decltype(&XXH3_freeState)> guard(st, XXH3_freeState);
  XXH3_64bits_reset(st);
  if (in.from_trace()) {
    FILE* f = std::fopen(in.trace_path.c_str(), "rb");
    if (!f) throw UserError(in.trace_path + ": " + std::strerror(errno));
    std::vector<char> buf(size_t(1) << 20);
    size_t n;
    while ((n = std::fread(buf.data(), 1, buf.size(), f)) > 0) XXH3_64bits_update(st, buf.data(), n);
    const bool bad = std::ferror(f);
    std::fclose(f);
    if (bad) throw UserError(in.trace_path + ": read error");
    // A repeated input is another input.
    const uint32_t r = in.repeat;
    XXH3_64bits_update(st, &r, sizeof r);
  } else {
    auto src = open_fragments(in);
    PayloadWriter p;
    put_header(p, src->header());
    for (Fragment f; src->next(f);) {
      canonicalise(src->header(), f);
      put_fragment(p, src->header(), f);
      if (p.bytes().size() >= (size_t(1) << 20)) {
        XXH3_64bits_update(st, p.bytes().data(), p.bytes().size());
        p.bytes().clear();
      }
    }
    XXH3_64bits_update(st, p.bytes().data(), p.bytes().size());
  }
  id.digest = XXH3_64bits_digest(st);
  return id;
}

}  // namespace ropsim
