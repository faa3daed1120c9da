// The functional (golden) model of the stochastic-transparency ROP and the
// comparison methods. No SystemC: this is the reference the cycle model is
// checked against, bit for bit.
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "numerics.h"
#include "sample_store.h"
#include "tile_map.h"
#include "tracker.h"
#include "trace.h"
#include "conversion_memo.h"

namespace ropsim {

enum class Method { kLk, kEnderton, kNaive, kA2c, kOpaque, kReference };

const char* to_string(Method m);
/// Parses a method name; returns false for an unknown name.
bool parse_method(const std::string& s, Method& out);
const std::vector<std::string>& method_names();

struct GoldenConfig {
  Method method = Method::kLk;
  Numerics numerics;
  uint64_t seed = 1;  ///< seeds the hash-based random numbers of enderton and naive
};

/// Event counts of one run. Units: counts, or bytes where named *_bytes.
struct Counters {
  uint64_t fragments = 0;               ///< fragments processed
  uint64_t samples_tested = 0;          ///< covered samples of those fragments
  uint64_t samples_depth_passed = 0;    ///< samples that passed the depth test
  uint64_t samples_opacity_passed = 0;  ///< samples that passed the opacity decision
  uint64_t samples_written = 0;         ///< samples whose depth and colour were written
  uint64_t surface_id_changes = 0;      ///< lk: new surfaces started by a bitmask conflict
  uint64_t sorts = 0;                   ///< lk: fragments with >= 2 surviving samples to sort
  uint64_t depth_bytes_read = 0;        ///< 4 bytes per tested sample
  uint64_t depth_bytes_written = 0;     ///< 4 bytes per written sample
  uint64_t color_bytes_written = 0;     ///< 6 bytes (RGB16F) per written sample
  uint64_t tracker_bytes_read = 0;      ///< lk: ceil((spp + surface_id_bits) / 8) per fragment
  uint64_t tracker_bytes_written = 0;   ///< lk: the same, per fragment that changed the state
  uint64_t tiles_touched = 0;           ///< 8x8-pixel tiles with allocated state
};

class FunctionalModel {
 public:
  virtual ~FunctionalModel() = default;
  /// Processes one fragment (in API order).
  virtual void draw(const Fragment& f) = 0;
  /// Box-filter resolve of every pixel; untouched pixels get the clear colour.
  virtual Image resolve() const = 0;
  /// Host bytes of per-pixel state currently allocated.
  virtual size_t state_bytes() const = 0;
  const Counters& counters() const { return counters_; }
  const TraceHeader& header() const { return header_; }

 protected:
  FunctionalModel(const TraceHeader& h) : header_(h) {}
  TraceHeader header_;
  Counters counters_;
};

/// The per-sample z-buffer methods (lk, enderton, naive, a2c, opaque).
class StochasticModel : public FunctionalModel {
 public:
  StochasticModel(const TraceHeader& h, const GoldenConfig& cfg);
  void draw(const Fragment& f) override;
  Image resolve() const override;
  size_t state_bytes() const override;
  /// The full per-sample state (depth, colour, tracker).
  const SampleStore& store() const { return store_; }
  /// Read-only view of one pixel's state; all pointers null if the pixel's
  /// tile was never touched (it then holds the clear values).
  PixelView pixel_view(uint32_t x, uint32_t y) const { return store_.view(x, y); }
  const GoldenConfig& config() const { return cfg_; }

 private:
  void count_written(uint32_t n);  ///< samples_written and the state bytes they cost
  void sample_depths(const Fragment& f, float* z) const;     ///< as fragment_sample_depths
  uint64_t fixed_alpha(float alpha) { return memo_.fixed_alpha(alpha); }
  const uint16_t* half_color(const std::array<float, 3>& rgb) { return memo_.half_color(rgb); }
  void draw_lk(const Fragment& f);
  void draw_enderton(const Fragment& f);
  void draw_naive(const Fragment& f);
  void draw_a2c(const Fragment& f);
  void draw_opaque(const Fragment& f);

  GoldenConfig cfg_;
  SampleStore store_;
  uint32_t hilbert_n_;
  uint64_t alpha_one_;  // 2^alpha_bits
  int tracker_bytes_;
  std::array<uint64_t, 65> a2c_prefix_{};  // a2c: mask of the first k samples in the fixed order
  void (StochasticModel::*draw_fn_)(const Fragment&);
  std::array<float, 64> offset_x_{}, offset_y_{};  // sample offsets from the pixel centre
  ConversionMemo memo_;
};

/// Ground truth: an A-buffer keeping every fragment of every sample, sorted by
/// depth and composited with the over operator at resolve.
class ReferenceModel : public FunctionalModel {
 public:
  explicit ReferenceModel(const TraceHeader& h);
  void draw(const Fragment& f) override;
  Image resolve() const override;
  size_t state_bytes() const override;

 private:
  struct Entry {
    uint64_t coverage;
    size_t z_offset;  // into z_, popcount(coverage) depths in sample order
    std::array<float, 3> rgb;
    float alpha;
    uint32_t seq;   // API order within the pixel's list
    int64_t next;   // previous entry of the same pixel, -1 at the end
  };
  struct HeadTile {
    std::array<int64_t, 64> head;
  };
  TileMap<HeadTile> heads_;
  std::vector<Entry> entries_;
  std::vector<float> z_;
};

std::unique_ptr<FunctionalModel> make_functional_model(const TraceHeader& h, const GoldenConfig& cfg);

}  // namespace ropsim
