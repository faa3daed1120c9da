// Hardware-implementable random numbers for the comparison methods: a hash of
// (seed, draw, primitive, pixel, lane), never a stateful generator, so results
// do not depend on processing order (docs/numerics.md "Random numbers").
#pragma once
#include <cstdint>

namespace ropsim {

/// splitmix64 finaliser (Steele, Lea & Flood 2014): a bijective 64-bit mixer.
inline uint64_t mix64(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

/// Key of one fragment: mixes seed, draw id, primitive id and the pixel.
inline uint64_t fragment_key(uint64_t seed, uint32_t draw, uint32_t prim, uint32_t x, uint32_t y) {
  uint64_t h = mix64(seed ^ 0x9E3779B97F4A7C15ull);
  h = mix64(h ^ (uint64_t{draw} << 32 | prim));
  h = mix64(h ^ (uint64_t{x} << 32 | y));
  return h;
}

/// The lane-th 32-bit random number of a fragment (lane 0 = xi, lanes 1.. for
/// sample choices or per-sample references).
inline uint32_t fragment_random(uint64_t key, uint32_t lane) {
  return static_cast<uint32_t>(mix64(key + 0x9E3779B97F4A7C15ull * (uint64_t{lane} + 1)) >> 32);
}

}  // namespace ropsim
