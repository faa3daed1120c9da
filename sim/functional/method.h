// The transparency methods and their traits: which stages of the functional
// ROP each one uses. The golden model runs those stages in order; the cycle
// pipeline instantiates a unit for each of them and no other. One table, read
// by both (method.cpp).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "numerics.h"

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
};
/// The last enumerator (method.cpp checks that every one has its row).
inline constexpr Method kLastMethod = Method::kSlab;

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
};

/// The traits of a method (usable at compile time).
constexpr const MethodTraits& traits(Method m) {
  for (const auto& t : kMethodTable)
    if (t.method == m) return t;
  return kMethodTable[0];  // unreachable: every enumerator has a row (method.cpp checks)
}
const char* to_string(Method m);
/// Parses a method name; returns false for an unknown name.
bool parse_method(const std::string& s, Method& out);
const std::vector<std::string>& method_names();

/// A method and what parameterises it.
struct MethodConfig {
  Method method = Method::kLk;
  Numerics numerics;
  uint64_t seed = 1;    ///< seeds the hash-based random numbers of enderton, naive, hashed, hashed-a2c and slab
  int slab_layers = 8;  ///< slab: k, layers per pixel (1..16; Wyman 2016's k = 8)
  int slab_bits = 32;   ///< slab: b, bits of each layer's coverage mask (1..64; Wyman 2016's b = 32)
};
/// The golden model's name for the same configuration.
using GoldenConfig = MethodConfig;

}  // namespace ropsim
