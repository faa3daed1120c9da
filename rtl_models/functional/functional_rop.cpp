#include "rtl_models/functional/functional_rop.h"

#include <stdexcept>

#include "rtl_models/algo/hilbert.h"
#include "rtl_models/algo/method_kernels.h"
#include "rtl_models/functional/composite.h"
#include "rtl_models/functional/framebuffer_blend.h"
#include "util/errors.h"

namespace ropsim {

RopSetup::RopSetup(const TraceHeader& h, const MethodConfig& c)
    : header(h),
      cfg([&c] {
        MethodConfig r = c;
        r.formats = target_formats(c);
        return r;
      }()),
      traits(ropsim::traits(c.method)),
      selection(selection_of(c.method)),
      passes(run_passes(h, c.method)),
      pass(passes.pass[0]),
      spp(h.spp),
      hilbert_n(hilbert_side(h.width, h.height)),
      tracker_bytes(tracker_state_bytes(h.spp, c.numerics.surface_id_bits)),
      a2c_prefix(a2c_prefix_table(h.spp)) {
  if (const char* err = validate(c.numerics)) throw UserError(err);
  if (c.method == Method::kSlab) {
    if (const char* err = validate_slab(c.slab_layers, c.slab_bits)) throw UserError(err);
    slab_bits_of = slab_sample_bits(h.spp, c.slab_bits);
    slab_bytes = slab_pixel_bytes(c.slab_layers, c.slab_bits);
  }
  draw_states = !h.draws.empty();
  encoding = frame_encoding(h.draws);
  routed = has_routed_draws(h);
  prepass = passes.pass[0] == PassKind::kPrepass;
  bytes = surface_bytes(h, store_targets(h, c));
  for (int i = 0; i < h.spp; ++i) {
    offset_x[size_t(i)] = sample_offset(h.positions[size_t(i)].x);
    offset_y[size_t(i)] = sample_offset(h.positions[size_t(i)].y);
  }
}

bool has_routed_draws(const TraceHeader& h) {
  for (const DrawState& d : h.draws.states())
    if (route_of(draw_kind(d)) != DrawRoute::kMethod) return true;
  return false;
}

PassList run_passes(const TraceHeader& h, Method m) {
  const PassList own = passes_of(m);
  if (!composites_over_background(m) || !has_routed_draws(h)) return own;
  PassList p;
  p.pass[p.count++] = PassKind::kPrepass;
  for (int i = 0; i < own.count; ++i) p.pass[p.count++] = own.pass[i];
  return p;
}

bool runs_prepass(const TraceHeader& h, Method m) { return run_passes(h, m).pass[0] == PassKind::kPrepass; }

StoreTargets store_targets(const TraceHeader& h, const MethodConfig& cfg) {
  const bool prepass = runs_prepass(h, cfg.method);
  StoreTargets t{run_uses_transmittance(cfg.method, prepass),
                 run_uses_accum(cfg.method, prepass),
                 target_formats(cfg),
                 {0.0f, 0.0f, 0.0f, 0.0f},
                 cfg.method == Method::kSlab ? cfg.slab_bits : 0,
                 traits(cfg.method).framebuffer};
  if (traits(cfg.method).framebuffer) t.accum_clear = framebuffer_clear(frame_encoding(h.draws), h.clear_color);
  t.planes = cfg.compression.plane_keys();
  return t;
}

// ------------------------------------------------------------ FunctionalRop

template <Method M>
void FunctionalRop::process_as(FragWork& w) {
  constexpr MethodTraits kT = ropsim::traits(selection_of(M));
  fetch(w);
  if constexpr (has_blend_pass(M)) {
    if (is_blend_pass(setup_.pass)) {
      // The targets' samples are read-modify-written once the depth test has
      // run: ask for their cache lines now, so the loads overlap the test.
      blend_.prefetch(w);
      depth_.run_as<M>(w);  // not writing: the blend passes leave depth as it is
      if (w.killed()) return;
      blend_.run(w);
      return;
    }
  }
  depth_.run_as<M>(w);
  if (w.killed()) return;
  if constexpr (M != Method::kBlend) {
    // A frame's opaque or blended draw (single-pass methods, and the
    // pre-pass of the others): a z-buffer's write or a blend.
    if (w.route != DrawRoute::kMethod) {
      write_.run_routed(w);
      return;
    }
  }
  if constexpr (kT.tracker) track_.run(w);
  if constexpr (kT.sorter) sort_.run(w);
  if constexpr (kT.reference) reference_.run_as<M>(w);
  write_.run_as<M>(w);
}

FunctionalRop::FunctionalRop(const TraceHeader& h, const MethodConfig& cfg)
    : setup_(h, cfg),
      store_(h, setup_.traits.tracker, store_targets(h, cfg)),
      depth_(setup_),
      track_(setup_),
      sort_(setup_),
      reference_(setup_),
      write_(setup_),
      blend_(setup_) {
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
#define ROPSIM_CASE(M)                        \
  case M:                                     \
    process_ = &FunctionalRop::process_as<M>; \
    break;
      ROPSIM_CASE(Method::kWboit)
      ROPSIM_CASE(Method::kLkAc)
      ROPSIM_CASE(Method::kLkDepth)
      ROPSIM_CASE(Method::kLkDepthAc)
      ROPSIM_CASE(Method::kEndertonAc)
      ROPSIM_CASE(Method::kEndertonDepth)
      ROPSIM_CASE(Method::kEndertonDepthAc)
      ROPSIM_CASE(Method::kBlend)
#undef ROPSIM_CASE
    case Method::kReference:
      throw UserError(std::string("the ") + setup_.traits.name + " method has no ROP pipeline");
  }
}

void FunctionalRop::absorb(FunctionalRop& o) {
  if (o.setup_.cfg.method != setup_.cfg.method || o.setup_.pass != setup_.pass)
    throw InternalError("FunctionalRop::absorb: the ROPs run different methods or passes");
  store_.absorb(o.store_);
  depth_.absorb(o.depth_);
  track_.absorb(o.track_);
  sort_.absorb(o.sort_);
  reference_.absorb(o.reference_);
  write_.absorb(o.write_);
  blend_.absorb(o.blend_);
}

Counters FunctionalRop::counters() const {
  Counters c = depth_.counters();
  c += track_.counters();
  c += sort_.counters();
  c += reference_.counters();
  c += write_.counters();
  c += blend_.counters();
  c.tiles_touched = store_.tiles();
  return c;
}

}  // namespace ropsim

namespace ropsim {

void FunctionalRop::begin_pass(int i) {
  invariant(i >= 0 && i < setup_.passes.count, "begin_pass: the pass is one of the method's passes");
  setup_.pass = setup_.passes.pass[i];
}

Image FunctionalRop::resolve() const {
  if (setup_.traits.framebuffer) return framebuffer_image(store_);
  // (The method's own passes: a pre-pass draws the background, not the image.)
  const bool per_sample = passes_of(setup_.cfg.method).count == 1 && !setup_.traits.wboit;
  if (per_sample && setup_.encoding != TargetEncoding::kFloat && setup_.cfg.method != Method::kSlab)
    return colour_buffer_image(store_, setup_.encoding);
  if (!per_sample) return composite(store_, setup_.cfg.method, setup_.prepass);  // (light on 8-bit targets)
  Image img = store_.resolve(setup_.prepass);
  encode_resolved(img, setup_.encoding);
  return img;
}

}  // namespace ropsim
