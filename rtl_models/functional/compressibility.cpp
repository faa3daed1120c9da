#include "rtl_models/functional/compressibility.h"

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "rtl_models/algo/bits.h"
#include "rtl_models/algo/compression.h"
#include "rtl_models/algo/depth.h"
#include "rtl_models/functional/surface_bytes.h"
#include "util/errors.h"
#include "util/prefetch.h"

namespace ropsim {

namespace {

const uint8_t* buffer_bytes(Buffer b, const SampleTile& t) {
  switch (b) {
    case Buffer::kDepth:
      return reinterpret_cast<const uint8_t*>(t.depth);
    case Buffer::kColor:
      return reinterpret_cast<const uint8_t*>(t.rgb);
    case Buffer::kTransmittance:
      return t.trans;
    case Buffer::kAccum:
      return t.accum;
    default:
      return nullptr;
  }
}

/// The pixels [first, first + tile_pixels) of t's surface b as memory holds
/// them (surface_bytes.h): t's own bytes, or converted into scratch.
const uint8_t* memory_bytes(const SurfaceBytes& sb, const SampleTile& t, Buffer b, uint32_t first, uint32_t tile_pixels,
                            uint32_t spp, std::vector<uint8_t>& scratch) {
  const uint8_t* host = buffer_bytes(b, t) + size_t(first) * spp * sb.host[size_t(b)];
  if (!sb.converts(b)) return host;
  const size_t n = size_t(tile_pixels) * spp;
  scratch.resize(n * sb.of(b));
  sb.store(b, host, n, scratch.data());
  return scratch.data();
}

/// The farthest of n depths, as std::max_element finds it: when none is
/// negative or NaN (bit patterns at most +inf's), the depths order as their
/// bit patterns do, and one pass over the patterns (vectorised) finds it.
float farthest(const float* z, size_t n) {
  uint32_t top = 0;
  for (size_t i = 0; i < n; ++i) {
    uint32_t bits;
    std::memcpy(&bits, &z[i], 4);
    top = std::max(top, bits);
  }
  if (top > 0x7F800000u) return *std::max_element(z, z + n);
  float m;
  std::memcpy(&m, &top, 4);
  return m;
}

/// A cleared tile of the store's buffers (to tell cleared memory tiles).
struct ClearTile {
  SampleStore store;
  const SampleTile* tile;
  explicit ClearTile(const SampleStore& s) : store(s.header(), s.has_tracker(), s.targets()) {
    store.pixel(0, 0);
    tile = store.tile_map().find(0, 0);
  }
};

/// The memory tile of pixels [first, first + tile_pixels) in surface b,
/// whose bytes as memory holds them are `data` (depth: its samples' plane
/// keys `planes`, nullptr unless the store keeps them); clear: a cleared tile.
TileState state_of(const SampleStore& store, const SurfaceBytes& sb, const uint8_t* data, const uint64_t* planes,
                   const SampleTile& clear, Buffer b, uint32_t first, const CompressionFormat& f, bool size = true) {
  TileState st;
  const uint32_t spp = uint32_t(store.header().spp), bps = sb.of(b);
  const size_t len = size_t(f.tile_pixels) * spp * bps;
  // A tile leaving the ROP cache was written long ago: ask for all its
  // lines at once, so that their misses overlap.
  prefetch_lines(data, len);
  if (planes && b == Buffer::kDepth && size) prefetch_lines(planes, size_t(f.tile_pixels) * spp * sizeof(uint64_t));
  if (b == Buffer::kDepth) {
    const float* z = reinterpret_cast<const float*>(data);
    st.max_depth = farthest(z, size_t(f.tile_pixels) * spp);
  }
  if (!size) return st;
  thread_local std::vector<uint8_t> clear_scratch;
  if (std::memcmp(data, memory_bytes(sb, clear, b, first, f.tile_pixels, spp, clear_scratch), len) == 0) {
    st.cleared = true;
    return st;
  }
  if (b == Buffer::kDepth && f.depth_encoder == DepthEncoder::kPlane) {
    if (!planes) throw InternalError("the rasterizer-plane depth encoder needs the store's plane keys");
    st.size = plane_depth_tile_size(DepthPlanesIn{planes, f.tile_pixels, int(spp)}, f);
  } else if (b == Buffer::kDepth) {
    const TraceHeader& h = store.header();
    uint8_t px[64], py[64];
    for (uint32_t s = 0; s < spp; ++s) {
      px[s] = h.positions[s].x;
      py[s] = h.positions[s].y;
    }
    st.size = depth_tile_size(DepthTileIn{reinterpret_cast<const float*>(data), f.tile_pixels, int(spp), px, py}, f);
  } else {
    st.size = color_tile_size(ColorTileIn{data, f.tile_pixels, int(spp), bps}, f);
  }
  return st;
}
TileState state_of(const SampleStore& store, const SurfaceBytes& sb, const SampleTile& t, const SampleTile& clear,
                   Buffer b, uint32_t first, const CompressionFormat& f, bool size = true) {
  thread_local std::vector<uint8_t> scratch;
  const uint32_t spp = uint32_t(store.header().spp);
  const uint8_t* data = memory_bytes(sb, t, b, first, f.tile_pixels, spp, scratch);
  const uint64_t* planes = t.plane ? t.plane + size_t(first) * spp : nullptr;
  return state_of(store, sb, data, planes, clear, b, first, f, size);
}

}  // namespace

bool compressible(Buffer b, const CompressionSetup& setup, const SampleStore& store) {
  switch (b) {
    case Buffer::kDepth:
      return setup.depth;
    case Buffer::kColor:
      return setup.color;
    case Buffer::kTransmittance:
      return setup.color && store.targets().transmittance;
    case Buffer::kAccum:
      return setup.color && store.targets().accum;
    default:
      return false;
  }
}

CompressionStats measure_compressibility(const SampleStore& store, const CompressionSetup& setup) {
  CompressionStats cs;
  if (!setup.any()) return cs;
  cs.measured = true;
  const CompressionFormat& f = setup.format;
  const TraceHeader& h = store.header();
  const uint64_t screen_tiles =
      uint64_t(ceil_div(h.width, 8u)) * uint64_t(ceil_div(h.height, 8u)) * (64u / f.tile_pixels);
  const ClearTile clear(store);
  const SurfaceBytes sb = surface_bytes(h, store.targets());
  for (int bi = 0; bi < kBuffers; ++bi) {
    const Buffer b = Buffer(bi);
    if (!compressible(b, setup, store)) continue;
    cs.compressed[size_t(bi)] = true;
    BufferCompression& bc = cs.buffers[size_t(bi)];
    bc.tiles = screen_tiles;
    bc.metadata_bytes = ceil_div(screen_tiles * uint64_t(metadata_bits(f)), uint64_t{8});
    const uint64_t U = uint64_t(f.tile_pixels) * uint64_t(h.spp) * sb.of(b);
    uint64_t seen = 0;
    store.tile_map().for_each([&](uint32_t, uint32_t, const SampleTile& t) {
      for (uint32_t first = 0; first < 64; first += f.tile_pixels) {
        ++seen;
        const TileState st = state_of(store, sb, t, *clear.tile, b, first, f);
        if (st.cleared) {
          ++bc.tiles_cleared;
          continue;
        }
        bc.bytes_uncompressed += U;
        bc.bytes_compressed += st.size.bytes;
        ++bc.tiles_per_class[size_t(st.size.size_class)];
      }
    });
    bc.tiles_cleared += screen_tiles - seen;  // untouched tiles
  }
  return cs;
}

struct TileCompressor::Clear : ClearTile {
  using ClearTile::ClearTile;
};

TileCompressor::TileCompressor(const SampleStore& store, const CompressionFormat& f)
    : store_(store),
      f_(f),
      bytes_(surface_bytes(store.header(), store.targets())),
      clear_(std::make_unique<Clear>(store)) {}
TileCompressor::~TileCompressor() = default;

TileState TileCompressor::state(Buffer b, uint32_t x, uint32_t y, bool size, const TilePatch* patches, size_t n) const {
  const SampleTile* t = store_.tile_map().find(x, y);
  if (!t) {
    TileState st;
    st.cleared = true;
    st.max_depth = canonical_depth(store_.header().clear_depth);
    return st;
  }
  const uint32_t first = uint32_t(pixel_in_tile(x, y)) / f_.tile_pixels * f_.tile_pixels;
  if (n == 0) return state_of(store_, bytes_, *t, *clear_->tile, b, first, f_, size);
  // The tile's bytes as memory holds them with the patches (the same bytes,
  // surface_bytes.h) over them (as floats: depth reads them so).
  const uint32_t spp = uint32_t(store_.header().spp);
  const size_t len = size_t(f_.tile_pixels) * spp * bytes_.of(b);
  thread_local std::vector<float> copy;
  thread_local std::vector<uint8_t> scratch;
  copy.resize((len + 3) / 4);
  uint8_t* bytes = reinterpret_cast<uint8_t*>(copy.data());
  std::memcpy(bytes, memory_bytes(bytes_, *t, b, first, f_.tile_pixels, spp, scratch), len);
  // Depth's plane keys likewise, each patch restoring its samples' keys.
  thread_local std::vector<uint64_t> keys;
  const bool planes = b == Buffer::kDepth && t->plane;
  if (planes) keys.assign(t->plane + size_t(first) * spp, t->plane + size_t(first + f_.tile_pixels) * spp);
  for (size_t i = 0; i < n; ++i) {
    if (size_t(patches[i].offset) + patches[i].len > len) throw InternalError("a tile patch lies outside its tile");
    std::memcpy(bytes + patches[i].offset, patches[i].old, patches[i].len);
    if (planes && patches[i].old_planes)
      std::memcpy(keys.data() + patches[i].offset / kDepthSampleBytes, patches[i].old_planes,
                  patches[i].len / kDepthSampleBytes * sizeof(uint64_t));
  }
  return state_of(store_, bytes_, bytes, planes ? keys.data() : nullptr, *clear_->tile, b, first, f_, size);
}

}  // namespace ropsim
