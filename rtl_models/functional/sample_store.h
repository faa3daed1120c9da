// The ROP's per-pixel buffers, functional view: depth (binary32) and colour
// (RGB binary16) per sample, and the LK tracker per pixel, in sparse 8 x 8
// tiles allocated on first touch. Shared by the golden model and the SystemC
// pipeline, so their final states can be compared sample for sample.
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <new>
#include <string>
#include <type_traits>

#include "rtl_models/algo/blend.h"
#include "rtl_models/algo/compression.h"
#include "rtl_models/algo/slab.h"
#include "rtl_models/algo/tracker.h"
#include "rtl_models/functional/image.h"
#include "traces/format/trace.h"
#include "util/containers/tile_map.h"
#include "util/memory_budget.h"
#include "util/prefetch.h"

namespace ropsim {

/// Where a tile's buffers lie in its block (SampleTileLayout), in bytes from
/// the block's start; 0: the store has no such buffer.
struct SampleTileLayout {
  size_t depth = 0, rgb = 0, tracker = 0, slab = 0, trans = 0, accum = 0, plane = 0;
  size_t bytes = 0;  ///< the whole block, the header included
};

/// The buffers of one 8 x 8 tile, in one block with the tile: the header,
/// then each buffer on a cache line of its own (at 16 spp a pixel's depths
/// fill one line). A pixel's state is found from the tile's address and the
/// store's layout, without reading the header first.
struct alignas(64) SampleTile {
  float* depth;           ///< [pixel * spp + sample]
  uint16_t* rgb;          ///< [(pixel * spp + sample) * 3 + channel]
  TrackerState* tracker;  ///< [pixel], nullptr unless tracking
  SlabPixel* slab;        ///< [pixel], nullptr unless slab
  uint8_t* trans;         ///< transmittance target, [(pixel * spp + sample) * bytes]; or nullptr
  uint8_t* accum;         ///< accumulation target, the same; or nullptr
  uint64_t* plane;        ///< [pixel * spp + sample] each depth's plane key (compression.h), or nullptr
  /// A tile in a block of l.bytes, its pointers set from l (buffers uninitialised).
  static std::unique_ptr<SampleTile> make(const SampleTileLayout& l);
  uint8_t* base() { return reinterpret_cast<uint8_t*>(this); }
  const uint8_t* base() const { return reinterpret_cast<const uint8_t*>(this); }
  static void operator delete(void* p) { ::operator delete (p, std::align_val_t{alignof(SampleTile)}); }

 private:
  SampleTile() = default;
};
static_assert(std::is_trivially_destructible_v<TrackerState> && std::is_trivially_destructible_v<SlabPixel>,
              "a tile's buffers are freed with its block, without destructors");

/// The per-pixel state beyond depth, colour and the tracker that a method
/// needs: the render targets it blends into, SLAB's layers (each allocated
/// only when used).
struct StoreTargets {
  bool transmittance = false;  ///< one channel, cleared to 1
  bool accum = false;          ///< RGBA, cleared to accum_clear
  BlendFormats formats;
  /// The accumulation target's clear value per channel (blend: the
  /// framebuffer's clear colour, framebuffer_blend.h).
  std::array<float, 4> accum_clear{0.0f, 0.0f, 0.0f, 0.0f};
  int slab_bits = 0;         ///< slab: b, the bits of each layer's mask (0: no SLAB layers)
  bool framebuffer = false;  ///< blend: the accumulation target is the application's framebuffer
  /// Each depth's plane key (the rasterizer-plane depth encoder, compression.h):
  /// the primitive that wrote it, kClearPlaneKey when cleared.
  bool planes = false;
};

/// Mutable pointers to one pixel's state.
struct PixelRef {
  float* depth;           ///< [spp]
  uint16_t* rgb;          ///< [spp * 3], binary16
  TrackerState* tracker;  ///< nullptr unless tracking
  SlabPixel* slab;        ///< nullptr unless slab
  uint8_t* trans;         ///< [spp * bytes] transmittance target, nullptr unless used
  uint8_t* accum;         ///< [spp * bytes] accumulation target, nullptr unless used
  uint64_t* plane;        ///< [spp] plane keys, nullptr unless kept
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
  const uint64_t* plane = nullptr;
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
  /// Asks the memory system for pixel (x, y)'s depth, colour and tracker
  /// lines, for a fragment drawn soon (a hint: changes nothing; nothing if
  /// its tile was never touched).
  void prefetch(uint32_t x, uint32_t y) const {
    const SampleTile* t = tiles_.find(x, y);
    if (!t) return;
    const PixelRef r = in_tile(t->base(), x, y);
    prefetch_lines<true>(r.depth, size_t(header_.spp) * sizeof(float));
    prefetch_lines<true>(r.rgb, size_t(header_.spp) * 3 * sizeof(uint16_t));
    if (r.tracker) __builtin_prefetch(r.tracker, 1);
  }
  /// Box-filter resolve of every pixel, samples summed in sample order;
  /// untouched pixels get the clear colour. slab: its layers over the clear
  /// colour, or with background_per_sample over each sample's colour (a
  /// pre-pass's opaque and blended draws: slab_resolve_over).
  Image resolve(bool background_per_sample = false) const;
  size_t state_bytes() const;
  /// Moves every tile of o, a store of the same screen and buffers holding
  /// none of this store's tiles, into this one (the golden model's threads
  /// each fill a store over their own tiles). Throws InternalError on a
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
  SampleTileLayout layout_;
  /// Pixel (x, y)'s state in the tile block at b, from the layout alone.
  PixelRef in_tile(const uint8_t* b, uint32_t x, uint32_t y) const;
  BudgetShare mem_;  // the tiles' bytes in the run's memory budget (--memory-limit)
  float clear_depth_;
  uint16_t clear_rgb16_[3];
};

/// The first difference between two stores' full state (every sample's depth
/// and colour bits, every tracker, every SLAB layer, every render target's bits), as "pixel (x, y) sample s: depth a vs
/// b"; empty if they are identical. Untouched tiles compare as the clear values.
std::string first_state_difference(const SampleStore& a, const SampleStore& b);

}  // namespace ropsim
