// The ROP's per-pixel buffers, functional view: depth (binary32) and colour
// (RGB binary16) per sample, and the LK tracker per pixel, in sparse 8 x 8
// tiles allocated on first touch. Shared by the golden model and the SystemC
// pipeline, so their final states can be compared sample for sample.
#pragma once
#include <cstdint>
#include <memory>
#include <string>

#include "blend.h"
#include "image.h"
#include "memory_budget.h"
#include "slab.h"
#include "tile_map.h"
#include "trace.h"
#include "tracker.h"

namespace ropsim {

/// The buffers of one 8 x 8 tile.
struct SampleTile {
  std::unique_ptr<float[]> depth;           ///< [pixel * spp + sample]
  std::unique_ptr<uint16_t[]> rgb;          ///< [(pixel * spp + sample) * 3 + channel]
  std::unique_ptr<TrackerState[]> tracker;  ///< [pixel], nullptr unless tracking
  std::unique_ptr<SlabPixel[]> slab;        ///< [pixel], nullptr unless slab
  std::unique_ptr<uint8_t[]> trans;         ///< transmittance target, [(pixel * spp + sample) * bytes]; or nullptr
  std::unique_ptr<uint8_t[]> accum;         ///< accumulation target, the same; or nullptr
};

/// The per-pixel state beyond depth, colour and the tracker that a method
/// needs: the render targets it blends into, SLAB's layers (each allocated
/// only when used).
struct StoreTargets {
  bool transmittance = false;  ///< one channel, cleared to 1
  bool accum = false;          ///< RGBA, cleared to 0
  BlendFormats formats;
  int slab_bits = 0;  ///< slab: b, the bits of each layer's mask (0: no SLAB layers)
};

/// Mutable pointers to one pixel's state.
struct PixelRef {
  float* depth;           ///< [spp]
  uint16_t* rgb;          ///< [spp * 3], binary16
  TrackerState* tracker;  ///< nullptr unless tracking
  SlabPixel* slab;        ///< nullptr unless slab
  uint8_t* trans;         ///< [spp * bytes] transmittance target, nullptr unless used
  uint8_t* accum;         ///< [spp * bytes] accumulation target, nullptr unless used
  void write_sample(int i, float z, const uint16_t* rgb16) {
    depth[i] = z;
    rgb[3 * i] = rgb16[0];
    rgb[3 * i + 1] = rgb16[1];
    rgb[3 * i + 2] = rgb16[2];
  }
};

/// Read-only view of one pixel; all pointers null if its tile was never touched.
struct PixelView {
  const float* depth = nullptr;
  const uint16_t* rgb = nullptr;
  const TrackerState* tracker = nullptr;
  const SlabPixel* slab = nullptr;
  const uint8_t* trans = nullptr;
  const uint8_t* accum = nullptr;
};

inline int pixel_in_tile(uint32_t x, uint32_t y) { return int((y & 7u) << 3 | (x & 7u)); }

class SampleStore {
 public:
  /// with_tracker: allocate the LK tracker state (lk only); targets: the
  /// render targets a method blends into, and SLAB's layers (slab only).
  SampleStore(const TraceHeader& h, bool with_tracker, const StoreTargets& targets = {});
  /// The pixel's state, its tile allocated and cleared on first touch.
  PixelRef pixel(uint32_t x, uint32_t y);
  PixelView view(uint32_t x, uint32_t y) const;
  /// Box-filter resolve of every pixel, samples summed in sample order;
  /// untouched pixels get the clear colour.
  Image resolve() const;
  size_t state_bytes() const;
  /// Moves every tile of o, a store of the same screen and buffers holding
  /// none of this store's tiles, into this one (the golden model's threads
  /// each fill a store over their own tiles). Throws std::logic_error on a
  /// tile both hold.
  void absorb(SampleStore& o);
  /// Copies the tile holding pixel (x, y) from src, a store of the same
  /// screen and buffers, into this one (allocating it here); nothing if src
  /// never touched it. A live-point's pre-state (sampled simulation).
  void copy_tile_from(const SampleStore& src, uint32_t x, uint32_t y);
  /// Copies pixel (x, y)'s state from src, a store of the same screen and
  /// buffers, allocating its tile here (cleared) if needed; the clear values
  /// if src never touched it.
  void copy_pixel_from(const SampleStore& src, uint32_t x, uint32_t y);
  /// The bytes of one touched tile's buffers.
  size_t tile_bytes() const;
  size_t tiles() const { return tiles_.tiles(); }
  const TileMap<SampleTile>& tile_map() const { return tiles_; }
  const TraceHeader& header() const { return header_; }
  bool has_tracker() const { return with_tracker_; }
  bool has_slab() const { return slab_bits_ > 0; }
  const StoreTargets& targets() const { return targets_; }

 private:
  TraceHeader header_;
  bool with_tracker_;
  int slab_bits_;
  StoreTargets targets_;
  TileMap<SampleTile> tiles_;
  BudgetShare mem_;  // the tiles' bytes in the run's memory budget (--memory-limit)
  float clear_depth_;
  uint16_t clear_rgb16_[3];
};

/// The first difference between two stores' full state (every sample's depth
/// and colour bits, every tracker, every SLAB layer, every render target's bits), as "pixel (x, y) sample s: depth a vs
/// b"; empty if they are identical. Untouched tiles compare as the clear values.
std::string first_state_difference(const SampleStore& a, const SampleStore& b);

}  // namespace ropsim
