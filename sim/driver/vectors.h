// Golden test vectors for RTL verification (docs/vectors.md): CSV with a
// header row, inputs then outputs, floats as IEEE-754 bit patterns in hex.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "numerics.h"

namespace ropsim {

const std::vector<std::string>& vector_units();
const std::vector<std::string>& vector_formats();

/// What else shapes a vector file besides the unit, the count, the seed and
/// the datapath widths.
struct VectorOptions {
  std::string format = "csv";  ///< csv (a header row, then one row per vector) or hex ($readmemh words)
  int spp = 0;                 ///< samples per pixel of every vector (0: 1..64 at random per vector)
  int hilbert_order = 0;       ///< hilbert: log2 of the grid side (0: 1..16 at random per vector)
};

/// The text of `count` vectors of `unit` (directed corner cases first, then
/// random cases from `seed`). The hex format is the CSV's rows re-encoded,
/// one fixed-width word per vector, with a comment block naming the fields'
/// bits (docs/vectors.md). Throws std::invalid_argument for an unknown unit
/// or an option out of range.
std::string make_vectors(const std::string& unit, uint64_t count, uint64_t seed, const Numerics& num,
                         const VectorOptions& opt = {});

}  // namespace ropsim
