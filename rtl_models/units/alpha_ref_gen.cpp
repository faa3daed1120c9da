#include "alpha_ref_gen.h"

#include "alpha_ref.h"
#include "hilbert.h"
#include "method_kernels.h"
#include "random_hash.h"

namespace ropsim {

PipeUnit::Timing AlphaRefGen::process(FragToken* t, uint64_t) {
  const Fragment& f = t->f;
  const Numerics& num = ctx_.golden.numerics;
  uint32_t hashes = 0;
  switch (ctx_.golden.method) {
    case Method::kLk: {
      const uint64_t pixel_id = hilbert_xy2d(ctx_.hilbert_n, f.x, f.y);
      calc_alpha_refs(t->tr.n, int(t->m), pixel_id, t->tr.surface_id, uint32_t(ctx_.header.spp), num.hash_bits,
                      t->ref);
      hashes = t->m;
      break;
    }
    case Method::kEnderton: {
      int m = 0;
      for (uint64_t s = t->survivors; s; s &= s - 1) t->list[m++] = __builtin_ctzll(s);
      const uint64_t key = fragment_key(ctx_.golden.seed, f.draw_id, f.prim_id, f.x, f.y);
      t->count = enderton_count(ctx_.fixed_alpha(f.alpha), num.alpha_bits, t->m, key);
      enderton_pick(t->list, t->m, t->count, key);
      hashes = t->count + 1;
      break;
    }
    case Method::kNaive: {
      const uint64_t key = fragment_key(ctx_.golden.seed, f.draw_id, f.prim_id, f.x, f.y);
      for (uint64_t s = t->survivors; s; s &= s - 1) {
        const int i = __builtin_ctzll(s);
        t->ref[i] = fragment_random(key, uint32_t(i) + 1);
      }
      hashes = t->m;
      break;
    }
    default: break;
  }
  stats_.samples += hashes;
  const uint32_t interval = std::max<uint32_t>(1, ceil_div(hashes, cfg_.lanes));
  return {interval, cfg_.pipeline_depth + interval - 1};
}

}  // namespace ropsim
