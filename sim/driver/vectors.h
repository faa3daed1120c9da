// Golden test vectors for RTL verification (docs/vectors.md): CSV with a
// header row, inputs then outputs, floats as IEEE-754 bit patterns in hex.
#pragma once
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "rtl_models/algo/numerics.h"
#include "rtl_models/functional/fragment_source.h"
#include "rtl_models/functional/method.h"
#include "util/errors.h"

namespace ropsim {

/// A vector request that cannot be met (an unknown unit, an option out of
/// range, an input the vectors' columns cannot hold): a user error.
class VectorError : public UserError {
 public:
  using UserError::UserError;
};

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
/// bits (docs/vectors.md). Throws VectorError for an unknown unit
/// or an option out of range.
std::string make_vectors(const std::string& unit, uint64_t count, uint64_t seed, const Numerics& num,
                         const VectorOptions& opt = {});

/// The units whose calls a replay captures (make_trace_vectors): every unit
/// of vector_units() that the functional ROP's stages call (half is
/// memoised, not called per fragment).
const std::vector<std::string>& trace_vector_units();

/// Which calls of a replay become vectors.
struct TraceVectorRequest {
  InputSpec input;      ///< the trace (or scene) replayed
  MethodConfig method;  ///< the method replayed; its numerics are the datapaths' widths
  std::string format = "csv";
  struct Window {
    uint32_t x0, y0, x1, y1;  ///< pixels x0 <= x <= x1, y0 <= y <= y1
  };
  std::optional<Window> window;  ///< only the calls for fragments of these pixels
  std::optional<uint32_t> draw;  ///< only the calls for fragments of this draw id
};

/// Replays the input through the golden model (one thread, every pass of
/// the method in order) and writes, through `write`, unit's vectors in the
/// format of make_vectors: the header (or the hex comment block), then one
/// row per call the ROP's stages make of the unit's rule, in the order made,
/// with the inputs and outputs the stage used (captured by a RopObserver,
/// not recomputed). Returns the rows written. Throws VectorError
/// for a unit --trace cannot capture, a method that never calls it, or a
/// depth-test input the vectors' columns cannot hold (per-sample depths,
/// sample positions other than the standard ones); TraceError or SceneError
/// for bad input.
uint64_t make_trace_vectors(const std::string& unit, const TraceVectorRequest& req,
                            const std::function<void(std::string_view)>& write);

}  // namespace ropsim
