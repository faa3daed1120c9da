#include "rop_context.h"

#include "depth.h"
#include "half.h"
#include "hilbert.h"
#include "method_kernels.h"
#include "opacity.h"
#include "pixel_ordering.h"

namespace ropsim {

RopContext::RopContext(const TraceHeader& h, const GoldenConfig& g, uint32_t line_bytes)
    : header(h), golden(g), store(h, g.method == Method::kLk),
      amap(h.width, h.spp, uint32_t((h.spp + g.numerics.surface_id_bits + 7) / 8), line_bytes),
      hilbert_n(hilbert_side(h.width, h.height)), tracker_bytes((h.spp + g.numerics.surface_id_bits + 7) / 8),
      a2c_prefix(a2c_prefix_table(h.spp)), memo_(g.numerics.alpha_bits) {
  for (int i = 0; i < h.spp; ++i) {
    offset_x[size_t(i)] = sample_offset(h.positions[size_t(i)].x);
    offset_y[size_t(i)] = sample_offset(h.positions[size_t(i)].y);
  }
}

void RopContext::retire(FragToken* t, uint64_t cycle) {
  ordering[t->rop]->release(t->pixel_key, cycle);
  ++retired;
  if (cycle > last_retire) last_retire = cycle;
  if (retire_hook) retire_hook(*t, cycle);
  pool.put(t);
}

}  // namespace ropsim
