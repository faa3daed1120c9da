#include "functional_rop.h"

#include <stdexcept>

#include "hilbert.h"
#include "method_kernels.h"

namespace ropsim {

RopSetup::RopSetup(const TraceHeader& h, const MethodConfig& c)
    : header(h),
      cfg(c),
      traits(ropsim::traits(c.method)),
      spp(h.spp),
      hilbert_n(hilbert_side(h.width, h.height)),
      tracker_bytes(tracker_state_bytes(h.spp, c.numerics.surface_id_bits)),
      a2c_prefix(a2c_prefix_table(h.spp)) {
  if (const char* err = validate(c.numerics)) throw std::invalid_argument(err);
  if (c.method == Method::kSlab) {
    if (const char* err = validate_slab(c.slab_layers, c.slab_bits)) throw std::invalid_argument(err);
    slab_bits_of = slab_sample_bits(h.spp, c.slab_bits);
    slab_bytes = slab_pixel_bytes(c.slab_layers, c.slab_bits);
  }
  for (int i = 0; i < h.spp; ++i) {
    offset_x[size_t(i)] = sample_offset(h.positions[size_t(i)].x);
    offset_y[size_t(i)] = sample_offset(h.positions[size_t(i)].y);
  }
}

// ------------------------------------------------------------ FunctionalRop

template <Method M>
void FunctionalRop::process_as(FragWork& w) {
  constexpr MethodTraits kT = ropsim::traits(M);
  fetch(w);
  depth_.run_as<M>(w);
  if (w.killed()) return;
  if constexpr (kT.tracker) track_.run(w);
  if constexpr (kT.sorter) sort_.run(w);
  if constexpr (kT.reference) reference_.run_as<M>(w);
  write_.run_as<M>(w);
}

FunctionalRop::FunctionalRop(const TraceHeader& h, const MethodConfig& cfg)
    : setup_(h, cfg),
      store_(h, setup_.traits.tracker, cfg.method == Method::kSlab ? cfg.slab_bits : 0),
      depth_(setup_),
      track_(setup_),
      sort_(setup_),
      reference_(setup_),
      write_(setup_) {
  switch (cfg.method) {
    case Method::kLk:
      process_ = &FunctionalRop::process_as<Method::kLk>;
      break;
    case Method::kEnderton:
      process_ = &FunctionalRop::process_as<Method::kEnderton>;
      break;
    case Method::kNaive:
      process_ = &FunctionalRop::process_as<Method::kNaive>;
      break;
    case Method::kA2c:
      process_ = &FunctionalRop::process_as<Method::kA2c>;
      break;
    case Method::kOpaque:
      process_ = &FunctionalRop::process_as<Method::kOpaque>;
      break;
    case Method::kHashed:
      process_ = &FunctionalRop::process_as<Method::kHashed>;
      break;
    case Method::kHashedA2c:
      process_ = &FunctionalRop::process_as<Method::kHashedA2c>;
      break;
    case Method::kSlab:
      process_ = &FunctionalRop::process_as<Method::kSlab>;
      break;
    case Method::kReference:
      throw std::invalid_argument(std::string("the ") + setup_.traits.name + " method has no ROP pipeline");
  }
}

Counters FunctionalRop::counters() const {
  Counters c = depth_.counters();
  c += track_.counters();
  c += sort_.counters();
  c += reference_.counters();
  c += write_.counters();
  c.tiles_touched = store_.tiles();
  return c;
}

}  // namespace ropsim
