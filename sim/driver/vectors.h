// Golden test vectors for RTL verification (docs/vectors.md): CSV with a
// header row, inputs then outputs, floats as IEEE-754 bit patterns in hex.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "numerics.h"

namespace ropsim {

const std::vector<std::string>& vector_units();

/// CSV text for `count` vectors of `unit` (directed corner cases first, then
/// random cases from `seed`). Throws std::invalid_argument for an unknown unit.
std::string make_vectors(const std::string& unit, uint64_t count, uint64_t seed, const Numerics& num);

}  // namespace ropsim
