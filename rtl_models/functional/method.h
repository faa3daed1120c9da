// The transparency methods and their traits: which stages of the functional
// ROP each one uses. The golden model runs those stages in order; the cycle
// pipeline instantiates a unit for each of them and no other. One table, read
// by both (method.cpp).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "rtl_models/algo/blend.h"
#include "rtl_models/algo/compression_format.h"
#include "rtl_models/algo/numerics.h"

namespace ropsim {

enum class Method {
  kLk,
  kEnderton,
  kNaive,
  kA2c,
  kOpaque,
  kReference,
  kHashed,
  kHashedA2c,
  kSlab,
  // Blending methods: weighted blended OIT, and lk / enderton with
  // Enderton et al.'s alpha correction (+ac) and depth-based accumulation (+depth).
  kWboit,
  kLkAc,
  kLkDepth,
  kLkDepthAc,
  kEndertonAc,
  kEndertonDepth,
  kEndertonDepthAc,
  // What today's GPUs execute: every fragment blended in submission order
  // with its draw's own blend and depth state (traces/format/draw_state.h).
  kBlend,
};
/// The last enumerator (method.cpp checks that every one has its row).
inline constexpr Method kLastMethod = Method::kBlend;

/// What one pass over the input does (docs/methods.md):
/// - kTotalAlpha: non-writing depth test, transmittance *= 1 - alpha;
/// - kStochastic: the method's stochastic z-buffer (writes depth, and colour
///   unless the method is depth-based; over a pre-pass, +ac's colour goes to
///   the accumulation target and +depth marks the transmittance target:
///   stochastic_colour_in_accum, stochastic_marks_transmittance);
/// - kAccumulate: non-writing depth test against the stochastic depth,
///   accum += (alpha c, alpha);
/// - kWboit: non-writing depth test, accum += (alpha c w, alpha w) and
///   transmittance *= 1 - alpha;
/// - kFramebuffer: the draw's depth test (and write, as its mask says), then
///   the draw's blend into the framebuffer (framebuffer_blend.h);
/// - kPrepass: on a frame of draw states, before a composite method's or
///   slab's passes: the opaque and blended draws only, each with its own
///   depth test and write and its blend into the colour buffer, which then
///   holds the background the method composites over (run_passes).
enum class PassKind : uint8_t { kTotalAlpha, kStochastic, kAccumulate, kWboit, kFramebuffer, kPrepass };
const char* to_string(PassKind p);
/// Does the pass blend into the render targets (the blend unit) rather than
/// write through the stochastic path (tracker, sorter, references, writeback)?
/// The pre-pass writes through the stochastic path, its units passing the
/// opaque and blended draws through.
constexpr bool is_blend_pass(PassKind p) { return p != PassKind::kStochastic && p != PassKind::kPrepass; }

/// What a method needs of the ROP. Every method with a pipeline has the depth
/// test and the writeback (opacity test and write); the rest is per method.
struct MethodTraits {
  Method method;
  const char* name;
  const char* summary;   ///< one line for --help and the docs
  bool pipeline;         ///< runs on the ROP (false: the A-buffer ground truth)
  bool coverage_select;  ///< a2c, hashed, hashed-a2c: a sample mask chosen before the depth test
  bool tracker;          ///< lk: the coverage-bitmask surface tracker (per-pixel state)
  bool sorter;           ///< lk: survivors sorted by the depth already stored
  bool reference;        ///< lk, enderton, naive: the alpha-reference generator (hashes)
  // Blending methods; the rows above leave these at their defaults.
  int base = -1;             ///< the method whose stochastic pass this one runs (-1: itself)
  bool total_alpha = false;  ///< +ac: a total-alpha pass first; the composite corrects to its alpha
  bool depth_based = false;  ///< +depth: the stochastic pass writes depth only; then an accumulation pass
  bool wboit = false;        ///< wboit: one blend pass into accum and transmittance
  bool framebuffer = false;  ///< blend: one pass blending into the framebuffer with each draw's state
};

/// The traits of every method, in the order of method_names().
//                                                  pipeline select tracker sorter reference
inline constexpr MethodTraits kMethodTable[] = {
    {Method::kLk, "lk", "Laine & Karras 2011: stratified stochastic transparency", true, false, true, true, true},
    {Method::kEnderton, "enderton", "Enderton et al. 2010: R = floor(alpha m + xi) depth survivors chosen at random",
     true, false, false, false, true},
    {Method::kNaive, "naive", "naive stochastic transparency: one random reference per sample", true, false, false,
     false, true},
    {Method::kA2c, "a2c", "alpha-to-coverage: a dithered fixed sample mask", true, true, false, false, false},
    {Method::kOpaque, "opaque", "a plain z-buffer: every covered sample that passes is written", true, false, false,
     false, false},
    {Method::kReference, "reference", "A-buffer ground truth: every fragment of every sample, sorted", false, false,
     false, false, false},
    {Method::kHashed, "hashed", "Wyman & McGuire 2017: hashed alpha test, one hashed threshold per fragment", true,
     true, false, false, false},
    {Method::kHashedA2c, "hashed-a2c",
     "Wyman & McGuire 2017 Eq. 9: hashed alpha-to-coverage, one threshold per 1/spp stratum in a hashed order", true,
     true, false, false, false},
    {Method::kSlab, "slab",
     "Wyman 2016: stochastic layered alpha blending, k layers of depth, colour and a b-bit mask per pixel", true, false,
     false, false, false},
    // Append new rows here, in enumerator order.
    {Method::kWboit, "wboit", "McGuire & Bavoil 2013: weighted blended OIT, one additive and multiplicative pass", true,
     false, false, false, false, -1, false, false, true},
    {Method::kLkAc, "lk+ac", "lk with alpha correction (Enderton et al. 3.3): total-alpha pass, then lk", true, false,
     true, true, true, int(Method::kLk), true, false, false},
    {Method::kLkDepth, "lk+depth",
     "lk depth-based (Enderton et al. 3.4): lk depth-only pass, then an accumulation pass", true, false, true, true,
     true, int(Method::kLk), false, true, false},
    {Method::kLkDepthAc, "lk+depth+ac", "lk depth-based with alpha correction: total alpha, lk depth, accumulation",
     true, false, true, true, true, int(Method::kLk), true, true, false},
    {Method::kEndertonAc, "enderton+ac", "enderton with alpha correction: total-alpha pass, then enderton", true, false,
     false, false, true, int(Method::kEnderton), true, false, false},
    {Method::kEndertonDepth, "enderton+depth",
     "enderton depth-based (Enderton et al. 3.4): depth-only pass, then an accumulation pass", true, false, false,
     false, true, int(Method::kEnderton), false, true, false},
    {Method::kEndertonDepthAc, "enderton+depth+ac",
     "enderton depth-based with alpha correction: total alpha, depth, accumulation", true, false, false, false, true,
     int(Method::kEnderton), true, true, false},
    {Method::kBlend, "blend",
     "what GPUs execute: each fragment in submission order, with its draw's blend and depth state", true, false, false,
     false, false, -1, false, false, false, true},
};

/// The traits of a method (usable at compile time).
constexpr const MethodTraits& traits(Method m) {
  for (const auto& t : kMethodTable)
    if (t.method == m) return t;
  return kMethodTable[0];  // unreachable: every enumerator has a row (method.cpp checks)
}
/// The method whose stochastic pass (selection, references, write) M runs:
/// lk for lk+ac, lk+depth and lk+depth+ac; enderton for its variants; M itself
/// otherwise.
constexpr Method selection_of(Method m) { return traits(m).base < 0 ? m : Method(traits(m).base); }

/// The passes of a method over its input, in order (at most 4, with the
/// pre-pass of a frame of draw states).
struct PassList {
  PassKind pass[4]{};
  int count = 0;
};
constexpr PassList passes_of(Method m) {
  const MethodTraits& t = traits(m);
  PassList p;
  if (t.wboit) {
    p.pass[p.count++] = PassKind::kWboit;
    return p;
  }
  if (t.framebuffer) {
    p.pass[p.count++] = PassKind::kFramebuffer;
    return p;
  }
  if (t.total_alpha) p.pass[p.count++] = PassKind::kTotalAlpha;
  p.pass[p.count++] = PassKind::kStochastic;
  if (t.depth_based) p.pass[p.count++] = PassKind::kAccumulate;
  return p;
}
/// Does the method use the transmittance (accumulation) render target?
constexpr bool uses_transmittance(Method m) { return traits(m).total_alpha || traits(m).wboit; }
/// (blend: the accumulation target, in RGBA binary32, holds the framebuffer.)
constexpr bool uses_accum(Method m) { return traits(m).depth_based || traits(m).wboit || traits(m).framebuffer; }
/// Does the method have a blend pass (the blend unit, the render targets)?
constexpr bool has_blend_pass(Method m) { return uses_transmittance(m) || uses_accum(m); }
/// Does its stochastic pass write colour (not for depth-based methods)?
constexpr bool stochastic_writes_color(Method m) { return !traits(m).depth_based; }
/// Does the method composite its own targets (or slab its layers) over a
/// background, so that a frame's opaque and blended draws go first, in a
/// pre-pass (PassKind::kPrepass), rather than into the method's own buffers?
constexpr bool composites_over_background(Method m) {
  return !traits(m).framebuffer && (has_blend_pass(m) || m == Method::kSlab);
}
/// Over a pre-pass, the colour buffer holds the background, which the
/// stochastic pass must leave for the composite; and the depth buffer holds
/// the background's depth, which the stochastic pass overwrites, so that a
/// written sample cannot be told by its depth. So on a run with a pre-pass:
/// - +ac's stochastic pass writes (c, 1) into the accumulation target (a
///   separate multisampled target, as Enderton et al.'s implementation
///   renders it) instead of c into the colour buffer: written is accum.a != 0;
/// - +depth's depth-only pass writes 0 into the transmittance target, which
///   the method otherwise leaves unused, as a one-channel mask of the samples
///   it wrote: written is T = 0.
/// Without a pre-pass both write as the method's passes say (colour buffer,
/// depth only) and a written sample is one whose depth is not the clear depth.
constexpr bool stochastic_colour_in_accum(Method m, bool prepass) {
  return prepass && traits(m).total_alpha && !traits(m).depth_based;
}
constexpr bool stochastic_marks_transmittance(Method m, bool prepass) {
  return prepass && traits(m).depth_based && !traits(m).total_alpha;
}
/// Does the stochastic pass write colour into the colour buffer?
constexpr bool stochastic_writes_colour_buffer(Method m, bool prepass) {
  return stochastic_writes_color(m) && !stochastic_colour_in_accum(m, prepass);
}
/// The render targets a run of method m keeps, with or without a pre-pass.
constexpr bool run_uses_transmittance(Method m, bool prepass) {
  return uses_transmittance(m) || stochastic_marks_transmittance(m, prepass);
}
constexpr bool run_uses_accum(Method m, bool prepass) {
  return uses_accum(m) || stochastic_colour_in_accum(m, prepass);
}

const char* to_string(Method m);
/// Parses a method name; returns false for an unknown name.
bool parse_method(const std::string& s, Method& out);
const std::vector<std::string>& method_names();

/// Which samples enderton (and its +ac, +depth variants) chooses its R among:
/// the samples that passed the depth test (depth-first, the variant Laine &
/// Karras compare against; the default), or all covered samples before the
/// depth test, as Enderton et al.'s original (R = floor(alpha c + xi) of the c
/// covered samples, then the depth test; only those that pass are written).
enum class EndertonSelection : uint8_t { kDepthFirst, kOriginal };
const char* to_string(EndertonSelection s);
bool parse_enderton_selection(const std::string& s, EndertonSelection& out);

/// A method and what parameterises it.
struct MethodConfig {
  Method method = Method::kLk;
  Numerics numerics;
  uint64_t seed = 1;     ///< seeds the hash-based random numbers of enderton, naive, hashed, hashed-a2c and slab
  int slab_layers = 8;   ///< slab: k, layers per pixel (1..16; Wyman 2016's k = 8)
  int slab_bits = 32;    ///< slab: b, bits of each layer's coverage mask (1..64; Wyman 2016's b = 32)
  BlendFormats formats;  ///< the blend targets' formats (the design's blend.*_format)
  EndertonSelection enderton_selection = EndertonSelection::kDepthFirst;  ///< enderton and its variants
  /// Surface compression (the design's [compression]): the functional run
  /// reports the final buffers' compressibility; it never changes the state.
  CompressionSetup compression;
};
/// The formats of the blend targets a run of c uses: the design's, except that
/// blend's framebuffer is always RGBA binary32 (it holds 8-bit code values
/// exactly and float targets unrounded).
inline BlendFormats target_formats(const MethodConfig& c) {
  BlendFormats f = c.formats;
  if (traits(c.method).framebuffer) f.accum = TargetFormat::kRGBA32F;
  return f;
}

/// c as a timing model runs it on a design compressing as `design` says:
/// its store keeps what the compressor needs (the depths' plane keys for the
/// rasterizer-plane encoder), whatever compression c itself names.
inline MethodConfig on_design(MethodConfig c, const CompressionSetup& design) {
  c.compression = design;
  return c;
}

/// The golden model's name for the same configuration.
using GoldenConfig = MethodConfig;

}  // namespace ropsim
