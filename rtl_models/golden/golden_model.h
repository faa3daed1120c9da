// The functional (golden) model: the functional ROP's stages called in order
// for every fragment (functional_rop.h), and the A-buffer ground truth. No
// SystemC: this is the fidelity the cycle model is checked against, bit for bit.
#pragma once
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "rtl_models/functional/counters.h"
#include "rtl_models/functional/functional_rop.h"
#include "rtl_models/functional/method.h"
#include "rtl_models/functional/sample_store.h"
#include "traces/format/trace.h"
#include "util/containers/tile_map.h"

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
  /// Processes n fragments in API order, as n calls of draw() would (a
  /// model on several threads runs them in parallel), and meanwhile calls
  /// beside(), if given, in the calling thread: work that must not touch this
  /// model (reading the next batch, say) overlaps the batch.
  virtual void draw_batch(const Fragment* f, size_t n, const std::function<void()>& beside = {}) {
    if (beside) beside();
    for (size_t i = 0; i < n; ++i) draw(f[i]);
  }
  /// Box-filter resolve of every pixel; untouched pixels get the clear colour.
  virtual Image resolve() const = 0;
  /// Host bytes of per-pixel state currently allocated.
  virtual size_t state_bytes() const = 0;
  /// Event counts so far.
  virtual Counters counters() const = 0;
  /// Fragments so far by their draw's kind (all zero for a trace without
  /// draw states).
  virtual DrawKindCounts kind_fragments() const = 0;
  const TraceHeader& header() const { return header_; }

 protected:
  FunctionalModel(const TraceHeader& h) : header_(h) {}
  TraceHeader header_;
};

/// The per-sample z-buffer methods (every method with a ROP pipeline).
///
/// On several threads the screen's 8 x 8 tiles are dealt to lanes, each a
/// FunctionalRop of its own over only its tiles; a batch of fragments is
/// split by lane, keeping trace order within each, and the lanes run in
/// parallel (TBB). Every rule of the ROP reads and writes one pixel's state
/// only, so each pixel sees exactly the fragments, in exactly the order, of
/// one thread, and the counters are sums: the state, the image and the
/// counters are bit-identical for every thread count. The lanes' stores are
/// merged into one before the state is read (store(), pixel_view(), resolve()).
class StochasticModel : public FunctionalModel {
 public:
  /// threads: 1 runs in the calling thread, one lane; n > 1 runs 8 n lanes
  /// (so the work balances) on n threads.
  StochasticModel(const TraceHeader& h, const GoldenConfig& cfg, int threads = 1);
  ~StochasticModel() override;
  void draw(const Fragment& f) override;
  void draw_batch(const Fragment* f, size_t n, const std::function<void()>& beside = {}) override;
  int passes() const override { return lane0().passes(); }
  void begin_pass(int i) override;
  Image resolve() const override { return merged().resolve(); }
  size_t state_bytes() const override { return merged().store().state_bytes(); }
  Counters counters() const override;
  DrawKindCounts kind_fragments() const override { return merged().depth().kind_fragments(); }
  /// The full per-sample state (depth, colour, tracker).
  const SampleStore& store() const { return merged().store(); }
  /// Read-only view of one pixel's state; all pointers null if the pixel's
  /// tile was never touched (it then holds the clear values).
  PixelView pixel_view(uint32_t x, uint32_t y) const { return merged().store().view(x, y); }
  const GoldenConfig& config() const { return lane0().setup().cfg; }
  int threads() const { return threads_; }
  /// The store holding pixel (x, y)'s tile -- its lane's, without merging
  /// the lanes (between batches: the state after every fragment drawn).
  const SampleStore& store_of(uint32_t x, uint32_t y) const;
  /// Calls f(lo, hi) over [0, n) in chunks on the model's threads (in the
  /// calling one when it has one). Between batches, f may read the lanes'
  /// stores (store_of) concurrently.
  void parallel_for(size_t n, const std::function<void(size_t, size_t)>& f) const;
  /// Called for every fragment of draw_batch, with its index in the batch
  /// and its work record after the ROP processed it; on a lane's thread, so
  /// concurrently for fragments of different lanes (never for one index
  /// twice). Empty: nothing is called.
  void set_observer(std::function<void(size_t, const FragWork&)> f) { observer_ = std::move(f); }
  /// Tells o (not owned; null: nobody) every unit call of every lane's ROP
  /// (FunctionalRop::set_observer, rop_observer.h). On several threads the
  /// lanes call it concurrently; on one, in API order.
  void set_rop_observer(RopObserver* o);
  /// Like set_observer, with what the fragment added to the counters (every
  /// counter, so the deltas of a run add up to counters() exactly). Costs two
  /// counter snapshots per fragment; empty: nothing is called.
  void set_counts_observer(std::function<void(size_t, const FragWork&, const Counters&)> f) {
    counts_observer_ = std::move(f);
  }

 private:
  struct Lane;
  static constexpr int kLanesPerThread = 8;
  void draw_lane(size_t lane, const Fragment* f, size_t n);
  const FunctionalRop& lane0() const;
  /// The lane owning pixel (x, y)'s tile.
  size_t lane_of(uint32_t x, uint32_t y) const;
  /// Lane 0 after the other lanes' state was moved into it (once; later
  /// draws then run on lane 0 alone).
  const FunctionalRop& merged() const;
  int threads_;
  std::function<void(size_t, const FragWork&)> observer_;
  std::function<void(size_t, const FragWork&, const Counters&)> counts_observer_;
  /// Processes one fragment on lane l and tells the observers (index i).
  void process_on(Lane& l, size_t i);
  mutable std::vector<std::unique_ptr<Lane>> lanes_;
  struct Pool;
  std::unique_ptr<Pool> pool_;  // the threads (n > 1)
};

/// Ground truth: an A-buffer keeping every fragment of every sample, sorted by
/// depth and composited with the over operator at resolve. On a frame of
/// draw states the A-buffer holds the src-over draws' fragments; the opaque
/// and blended draws go into a colour and depth buffer in submission order,
/// each with its own state, as every method's opaque and blended draws do
/// (the opaque method's ROP runs them), and the sorted fragments in front of
/// its depth are composited over its colour (docs/methods.md).
class ReferenceModel : public FunctionalModel {
 public:
  explicit ReferenceModel(const TraceHeader& h);
  ~ReferenceModel() override;
  void draw(const Fragment& f) override;
  Image resolve() const override;
  size_t state_bytes() const override;
  Counters counters() const override;
  DrawKindCounts kind_fragments() const override { return kinds_; }
  /// The least state one fragment adds (its list entry and one depth).
  static constexpr size_t kBytesPerFragmentAtLeast = 48 + sizeof(float);

 private:
  Counters counters_;
  RopSetup setup_;                       // the per-sample depths
  std::unique_ptr<FunctionalRop> base_;  // the opaque and blended draws (a frame with some)
  DrawKindCounts kinds_{};
  struct Entry {
    uint64_t coverage;
    size_t z_offset;  // into z_, popcount(coverage) depths in sample order
    std::array<float, 3> rgb;
    float alpha;
    uint32_t seq;            // API order within the pixel's list
    int64_t next;            // previous entry of the same pixel, -1 at the end
    bool depth_test = true;  // its draw's depth test is on (off: hidden only by opaque fragments drawn after it)
    uint32_t order = 0;      // its place in the frame's submission order (1, 2, ...)
  };
  struct HeadTile {
    std::array<int64_t, 64> head;
    /// Per pixel and sample (pixel-major): the submission order of the last
    /// opaque fragment that wrote the sample's colour, 0 for none; made at
    /// the tile's first such write.
    std::unique_ptr<uint32_t[]> opaque_order;
  };
  uint32_t order_ = 0;  // fragments drawn so far
  /// A src-over draw of the frame tests no depth: opaque writes are then
  /// ordered (HeadTile::opaque_order); otherwise nothing needs their order.
  bool untested_src_over_ = false;
  HeadTile& head_tile(uint32_t x, uint32_t y);
  TileMap<HeadTile> heads_;
  std::vector<Entry> entries_;
  std::vector<float> z_;
  static_assert(sizeof(Entry) >= 48, "kBytesPerFragmentAtLeast: an entry's bytes");
  BudgetShare mem_;  // state_bytes() as charged to the run's memory budget (--memory-limit)
};

/// The method's functional model; threads: the stochastic methods' threads
/// (StochasticModel), 0 for host_threads() (--threads). The reference runs
/// on one thread.
std::unique_ptr<FunctionalModel> make_functional_model(const TraceHeader& h, const GoldenConfig& cfg, int threads = 1);

}  // namespace ropsim
