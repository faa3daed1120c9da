// The functional (golden) model: the functional ROP's stages called in order
// for every fragment (functional_rop.h), and the A-buffer ground truth. No
// SystemC: this is the fidelity the cycle model is checked against, bit for bit.
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "counters.h"
#include "functional_rop.h"
#include "method.h"
#include "sample_store.h"
#include "tile_map.h"
#include "trace.h"

namespace ropsim {

class FunctionalModel {
 public:
  virtual ~FunctionalModel() = default;
  /// Passes over the input the method makes (method.h passes_of): the
  /// driver replays every fragment once per pass, calling begin_pass first.
  virtual int passes() const { return 1; }
  virtual void begin_pass(int) {}
  /// Processes one fragment (in API order).
  virtual void draw(const Fragment& f) = 0;
  /// Box-filter resolve of every pixel; untouched pixels get the clear colour.
  virtual Image resolve() const = 0;
  /// Host bytes of per-pixel state currently allocated.
  virtual size_t state_bytes() const = 0;
  /// Event counts so far.
  virtual Counters counters() const = 0;
  const TraceHeader& header() const { return header_; }

 protected:
  FunctionalModel(const TraceHeader& h) : header_(h) {}
  TraceHeader header_;
};

/// The per-sample z-buffer methods (every method with a ROP pipeline).
class StochasticModel : public FunctionalModel {
 public:
  StochasticModel(const TraceHeader& h, const GoldenConfig& cfg);
  void draw(const Fragment& f) override {
    work_.f = &f;
    rop_.process(work_);
  }
  int passes() const override { return rop_.passes(); }
  void begin_pass(int i) override { rop_.begin_pass(i); }
  Image resolve() const override { return rop_.resolve(); }
  size_t state_bytes() const override { return rop_.store().state_bytes(); }
  Counters counters() const override { return rop_.counters(); }
  /// The full per-sample state (depth, colour, tracker).
  const SampleStore& store() const { return rop_.store(); }
  /// Read-only view of one pixel's state; all pointers null if the pixel's
  /// tile was never touched (it then holds the clear values).
  PixelView pixel_view(uint32_t x, uint32_t y) const { return rop_.store().view(x, y); }
  const GoldenConfig& config() const { return rop_.setup().cfg; }

 private:
  FunctionalRop rop_;
  FragWork work_;
};

/// Ground truth: an A-buffer keeping every fragment of every sample, sorted by
/// depth and composited with the over operator at resolve.
class ReferenceModel : public FunctionalModel {
 public:
  explicit ReferenceModel(const TraceHeader& h);
  void draw(const Fragment& f) override;
  Image resolve() const override;
  size_t state_bytes() const override;
  Counters counters() const override { return counters_; }
  /// The least state one fragment adds (its list entry and one depth).
  static constexpr size_t kBytesPerFragmentAtLeast = 48 + sizeof(float);

 private:
  Counters counters_;
  RopSetup setup_;  // the per-sample depths
  struct Entry {
    uint64_t coverage;
    size_t z_offset;  // into z_, popcount(coverage) depths in sample order
    std::array<float, 3> rgb;
    float alpha;
    uint32_t seq;  // API order within the pixel's list
    int64_t next;  // previous entry of the same pixel, -1 at the end
  };
  struct HeadTile {
    std::array<int64_t, 64> head;
  };
  TileMap<HeadTile> heads_;
  std::vector<Entry> entries_;
  std::vector<float> z_;
  static_assert(sizeof(Entry) >= 48, "kBytesPerFragmentAtLeast: an entry's bytes");
  BudgetShare mem_;  // state_bytes() as charged to the run's memory budget (--memory-limit)
};

std::unique_ptr<FunctionalModel> make_functional_model(const TraceHeader& h, const GoldenConfig& cfg);

}  // namespace ropsim
