// A run's surface compression and Hi-Z (compression_model.h): the model of
// the design over the functional store's tiles. The cycle fidelity and the
// sampled fidelity's units build it here, the analytical model sizes its
// tag-only surfaces with the same bytes per sample.
#pragma once
#include <array>
#include <cstdint>
#include <memory>

#include "rtl_models/algo/depth.h"
#include "rtl_models/config/hw_config.h"
#include "rtl_models/functional/functional_rop.h"
#include "rtl_models/memory/compression_model.h"
#include "rtl_models/top/store_tile_source.h"

namespace ropsim {

/// The bytes per sample in memory of each surface a run of rop's method
/// uses (surface_bytes.h; 0: unused), as the compression models take them.
inline std::array<uint32_t, kBuffers> compressed_bytes_per_sample(const FunctionalRop& rop) {
  const SurfaceBytes& sb = rop.setup().bytes;
  const Method m = rop.setup().cfg.method;
  std::array<uint32_t, kBuffers> bps{};
  bps[size_t(Buffer::kDepth)] = sb.of(Buffer::kDepth);
  bps[size_t(Buffer::kColor)] = sb.of(Buffer::kColor);
  if (run_uses_transmittance(m, rop.setup().prepass))
    bps[size_t(Buffer::kTransmittance)] = sb.of(Buffer::kTransmittance);
  if (run_uses_accum(m, rop.setup().prepass)) bps[size_t(Buffer::kAccum)] = sb.of(Buffer::kAccum);
  return bps;
}

/// The compression model of a run and the store's tiles it sizes (the tiles
/// outlive the model, which reads them). Empty when the design neither
/// compresses a surface nor has Hi-Z.
struct SurfaceCompression {
  std::unique_ptr<StoreTileSource> tiles;
  std::unique_ptr<CompressionModel> model;
  CompressionModel* get() const { return model.get(); }
  CompressionModel* operator->() const { return model.get(); }
  explicit operator bool() const { return model != nullptr; }
};

/// The surface compression of a run of rop (its store, its method's
/// surfaces) on screen h under design hw.
inline SurfaceCompression compress_surfaces(const HwConfig& hw, const TraceHeader& h, FunctionalRop& rop) {
  SurfaceCompression c;
  if (!hw.compression.any() && !hw.hiz.enable) return c;
  c.tiles = std::make_unique<StoreTileSource>(rop.store(), hw.compression.setup().format);
  c.model = std::make_unique<CompressionModel>(hw, h.width, h.height, h.spp, compressed_bytes_per_sample(rop),
                                               canonical_depth(h.clear_depth), hw.distributor.rop_units);
  c.model->set_source(c.tiles.get());
  return c;
}

}  // namespace ropsim
