#include "rtl_models/golden/golden_model.h"

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <cmath>

#include "rtl_models/algo/depth.h"
#include "rtl_models/algo/half.h"
#include "rtl_models/functional/composite.h"
#include "util/errors.h"
#include "util/host_threads.h"

namespace ropsim {

// ------------------------------------------------------------ StochasticModel

struct StochasticModel::Lane {
  Lane(const TraceHeader& h, const GoldenConfig& cfg) : rop(h, cfg) {}
  FunctionalRop rop;
  FragWork work;
  /// Its fragments of the batch being drawn: indices into the batch, per
  /// chunk of the batch (each chunk partitioned by one thread), in API order.
  struct alignas(64) Part {
    std::vector<uint32_t> index;
  };
  std::vector<Part> parts;
};

struct StochasticModel::Pool {
  // TBB's own limit is the machine's cores; --threads may ask for more.
  explicit Pool(int threads) : limit(tbb::global_control::max_allowed_parallelism, size_t(threads)), arena(threads) {}
  tbb::global_control limit;
  tbb::task_arena arena;
};

StochasticModel::StochasticModel(const TraceHeader& h, const GoldenConfig& cfg, int threads)
    : FunctionalModel(h), threads_(std::max(1, threads)) {
  const int lanes = threads_ == 1 ? 1 : kLanesPerThread * threads_;
  for (int i = 0; i < lanes; ++i) lanes_.push_back(std::make_unique<Lane>(h, cfg));
  if (threads_ > 1) pool_ = std::make_unique<Pool>(threads_);
}

StochasticModel::~StochasticModel() = default;

const FunctionalRop& StochasticModel::lane0() const { return lanes_[0]->rop; }

void StochasticModel::set_rop_observer(RopObserver* o) {
  for (auto& l : lanes_) l->rop.set_observer(o);
}

size_t StochasticModel::lane_of(uint32_t x, uint32_t y) const {
  if (lanes_.size() == 1) return 0;
  // Tiles dealt by a hash of their position: neighbouring tiles land in
  // different lanes, so a dense region spreads over all of them.
  uint32_t k = (x >> 3) * 0x9E3779B1u ^ (y >> 3) * 0x85EBCA77u;
  k ^= k >> 15;
  k *= 0x2C1B3C6Du;
  k ^= k >> 12;
  return size_t(k % uint32_t(lanes_.size()));
}

const SampleStore& StochasticModel::store_of(uint32_t x, uint32_t y) const {
  return lanes_[lane_of(x, y)]->rop.store();
}

void StochasticModel::draw(const Fragment& f) {
  Lane& l = *lanes_[lane_of(f.x, f.y)];
  l.work.f = &f;
  l.rop.process(l.work);
}

void StochasticModel::process_on(Lane& l, size_t i) {
  if (counts_observer_) {
    const Counters before = l.rop.counters();
    l.rop.process(l.work);
    Counters delta = l.rop.counters();
    delta -= before;
    counts_observer_(i, l.work, delta);
  } else {
    l.rop.process(l.work);
  }
  if (observer_) observer_(i, l.work);
}

void StochasticModel::draw_lane(size_t li, const Fragment* f, size_t n) {
  Lane& l = *lanes_[li];
  for (size_t i = 0; i < n; ++i) {
    // The next fragment's pixel state, the one after's record, on their way
    // while this one runs.
    if (i + 1 < n) l.rop.store().prefetch(f[i + 1].x, f[i + 1].y);
    if (i + 2 < n) __builtin_prefetch(&f[i + 2]);
    l.work.f = &f[i];
    process_on(l, i);
  }
}

void StochasticModel::draw_batch(const Fragment* f, size_t n, const std::function<void()>& beside) {
  if (lanes_.size() == 1) {
    if (beside) beside();
    draw_lane(0, f, n);
    return;
  }
  // The batch in one chunk per thread, each partitioned among the lanes by
  // one thread; then each lane draws its fragments of chunk 0, 1, ... (API
  // order). Both steps run on every thread: no serial partition.
  const size_t chunks = size_t(threads_);
  for (auto& l : lanes_) l->parts.resize(chunks);
  auto run_lanes = [&] {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, chunks, 1), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t c = r.begin(); c != r.end(); ++c) {
        for (auto& l : lanes_) l->parts[c].index.clear();
        const size_t lo = n * c / chunks, hi = n * (c + 1) / chunks;
        for (size_t i = lo; i < hi; ++i) lanes_[lane_of(f[i].x, f[i].y)]->parts[c].index.push_back(uint32_t(i));
      }
    });
    tbb::parallel_for(tbb::blocked_range<size_t>(0, lanes_.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t li = r.begin(); li != r.end(); ++li) {
        Lane& l = *lanes_[li];
        for (const Lane::Part& part : l.parts) {
          const uint32_t* idx = part.index.data();
          const size_t m = part.index.size();
          for (size_t j = 0; j < m; ++j) {
            // The lane's fragments are scattered over the batch: fetch the
            // next one's pixel state and the one after's record while this
            // one runs.
            if (j + 1 < m) l.rop.store().prefetch(f[idx[j + 1]].x, f[idx[j + 1]].y);
            if (j + 2 < m) __builtin_prefetch(&f[idx[j + 2]]);
            l.work.f = &f[idx[j]];
            process_on(l, idx[j]);
          }
        }
      }
    });
  };
  pool_->arena.execute([&] {
    if (!beside) return run_lanes();
    // The lanes run as a task the arena's other threads take up, while this
    // thread does beside() and then joins them.
    tbb::task_group tg;
    tg.run(run_lanes);
    try {
      beside();
    } catch (...) {
      try {
        tg.wait();
      } catch (...) {
      }
      throw;
    }
    tg.wait();
  });
}

void StochasticModel::parallel_for(size_t n, const std::function<void(size_t, size_t)>& f) const {
  if (!pool_ || n < 2) {
    if (n > 0) f(0, n);
    return;
  }
  pool_->arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n),
                      [&](const tbb::blocked_range<size_t>& r) { f(r.begin(), r.end()); });
  });
}

void StochasticModel::begin_pass(int i) {
  for (auto& l : lanes_) l->rop.begin_pass(i);
}

Counters StochasticModel::counters() const {
  Counters c = lanes_[0]->rop.counters();
  for (size_t i = 1; i < lanes_.size(); ++i) c += lanes_[i]->rop.counters();
  return c;
}

const FunctionalRop& StochasticModel::merged() const {
  if (lanes_.size() > 1) {
    for (size_t i = 1; i < lanes_.size(); ++i) lanes_[0]->rop.absorb(lanes_[i]->rop);
    lanes_.resize(1);
  }
  return lanes_[0]->rop;
}

// ------------------------------------------------------------ ReferenceModel

namespace {
/// Room for `more` elements in v, its new capacity charged to the memory
/// budget before it is allocated: the lists grow with every fragment, so a
/// trace too large is refused in one line, not by std::bad_alloc.
template <class V>
void grow_for(V& v, size_t more, BudgetShare& mem) {
  if (v.size() + more <= v.capacity()) return;
  const size_t cap = std::max({v.capacity() * 2, v.size() + more, size_t{1024}});
  mem.add((cap - v.capacity()) * sizeof(typename V::value_type), "the A-buffer reference's fragment lists");
  v.reserve(cap);
}

MethodConfig reference_config() {
  MethodConfig c;
  c.method = Method::kReference;
  return c;
}
}  // namespace

ReferenceModel::ReferenceModel(const TraceHeader& h)
    : FunctionalModel(h), setup_(h, reference_config()), heads_(h.width, h.height) {
  mem_.add(heads_.directory_bytes(), "the A-buffer reference's tile directory");
  for (const DrawState& d : h.draws.states())
    untested_src_over_ = untested_src_over_ || (route_of(draw_kind(d)) == DrawRoute::kMethod && !d.depth_test);
  if (setup_.routed) {
    MethodConfig c;
    c.method = Method::kOpaque;
    base_ = std::make_unique<FunctionalRop>(h, c);
  }
}

ReferenceModel::~ReferenceModel() = default;

Counters ReferenceModel::counters() const {
  Counters c = counters_;
  if (base_) c += base_->counters();
  return c;
}

ReferenceModel::HeadTile& ReferenceModel::head_tile(uint32_t x, uint32_t y) {
  return heads_.get(x, y, [this](uint32_t, uint32_t) {
    mem_.add(sizeof(HeadTile), "the A-buffer reference's fragment lists");
    auto ht = std::make_unique<HeadTile>();
    ht->head.fill(-1);
    return ht;
  });
}

void ReferenceModel::draw(const Fragment& f) {
  std::array<float, 3> rgb = f.rgb;
  bool depth_test = true;
  const uint32_t order = ++order_;
  if (setup_.draw_states) {
    const DrawState& d = header_.draws.at(f.draw_id);
    depth_test = d.depth_test;
    const DrawKind k = draw_kind(d);
    ++kinds_[size_t(k)];
    if (route_of(k) != DrawRoute::kMethod) {  // the colour and depth buffer's, in submission order
      FragWork w;
      w.f = &f;
      base_->process(w);
      // An opaque fragment hides a src-over fragment drawn before it with its
      // depth test off (a sky drawn first, a compositor's shadow under a
      // window drawn after it): the samples whose colour it wrote, and when.
      if (untested_src_over_ && k == DrawKind::kOpaque && w.written) {
        HeadTile& t = head_tile(f.x, f.y);
        const size_t spp = size_t(header_.spp);
        if (!t.opaque_order) {
          t.opaque_order = std::make_unique<uint32_t[]>(64 * spp);
          mem_.add(64 * spp * sizeof(uint32_t), "the A-buffer reference's opaque write order");
        }
        uint32_t* o = t.opaque_order.get() + size_t(pixel_in_tile(f.x, f.y)) * spp;
        for (uint64_t m = w.written; m; m &= m - 1) o[__builtin_ctzll(m)] = order;
      }
      return;
    }
    rgb = transparent_rgb(d, f.rgb, f.alpha);
  }
  ++counters_.fragments;
  const int covered = __builtin_popcountll(f.coverage);
  counters_.samples_tested += covered;
  HeadTile& t = head_tile(f.x, f.y);
  int64_t& head = t.head[pixel_in_tile(f.x, f.y)];
  Entry e;
  e.coverage = f.coverage;
  e.z_offset = z_.size();
  e.rgb = rgb;
  e.alpha = f.alpha;
  e.seq = head < 0 ? 0 : entries_[size_t(head)].seq + 1;
  e.next = head;
  e.depth_test = depth_test;
  e.order = order;
  float z[64];
  setup_.sample_depths(f, f.coverage, z);
  grow_for(z_, size_t(covered), mem_);
  grow_for(entries_, 1, mem_);
  for (uint64_t m = f.coverage; m; m &= m - 1) z_.push_back(z[__builtin_ctzll(m)]);
  head = int64_t(entries_.size());
  entries_.push_back(e);
  counters_.tiles_touched = heads_.tiles();
}

Image ReferenceModel::resolve() const {
  // Pixels without src-over fragments: the colour buffer's box filter (the
  // clear colour without opaque and blended draws).
  const std::array<float, 3> clear = colour_buffer_clear(setup_.encoding, header_.clear_color);
  const TargetEncoding enc = setup_.encoding;
  const bool fixed = enc != TargetEncoding::kFloat;
  Image img = base_ ? (fixed ? colour_buffer_image(base_->store(), enc) : base_->store().resolve())
                    : Image(header_.width, header_.height,
                            fixed ? std::array<float, 3>{resolved_light(enc, clear[0]), resolved_light(enc, clear[1]),
                                                         resolved_light(enc, clear[2])}
                                  : clear);
  const float clear_z = canonical_depth(header_.clear_depth);
  const int spp = header_.spp;
  struct Layer {
    float z;
    uint32_t seq;
    const Entry* e;
  };
  std::vector<Layer> layers[64];
  heads_.for_each([&](uint32_t x0, uint32_t y0, const HeadTile& t) {
    for (int p = 0; p < 64; ++p) {
      if (t.head[p] < 0) continue;
      for (auto& l : layers) l.clear();
      for (int64_t ei = t.head[p]; ei >= 0; ei = entries_[size_t(ei)].next) {
        const Entry& e = entries_[size_t(ei)];
        size_t k = e.z_offset;
        for (uint64_t m = e.coverage; m; m &= m - 1) layers[__builtin_ctzll(m)].push_back(Layer{z_[k++], e.seq, &e});
      }
      double sum[3] = {0, 0, 0};
      float stored[64 * 4];  // an 8-bit target: each sample as it stores it
      const uint32_t x = x0 + uint32_t(p & 7), y = y0 + uint32_t(p >> 3);
      const PixelView bv = base_ ? base_->store().view(x, y) : PixelView{};
      for (int s = 0; s < spp; ++s) {
        auto& L = layers[s];
        // Behind the colour buffer's depth: hidden, as the methods' depth test
        // (LESS_EQUAL) hides it. A fragment whose draw tests no depth is
        // hidden where an opaque fragment drawn after it wrote the sample.
        double bg[3] = {clear[0], clear[1], clear[2]};
        if (base_) {
          const float zb = bv.depth ? bv.depth[s] : clear_z;
          const uint32_t after = t.opaque_order ? t.opaque_order[size_t(p) * size_t(spp) + size_t(s)] : 0;
          L.erase(std::remove_if(
                      L.begin(), L.end(),
                      [zb, after](const Layer& l) { return l.e->depth_test ? !(l.z <= zb) : after > l.e->order; }),
                  L.end());
          if (bv.rgb)
            for (int ch = 0; ch < 3; ++ch) bg[ch] = half_to_float(bv.rgb[3 * s + ch]);
        }
        // Nearest first; at equal depth the later fragment is in front, as the
        // LESS_EQUAL depth test of the stochastic methods decides.
        std::sort(L.begin(), L.end(),
                  [](const Layer& a, const Layer& b) { return a.z != b.z ? a.z < b.z : a.seq > b.seq; });
        double trans = 1.0, c[3] = {0, 0, 0};
        for (const Layer& l : L) {
          const double a = l.e->alpha;
          for (int ch = 0; ch < 3; ++ch) c[ch] += trans * a * l.e->rgb[ch];
          trans *= 1.0 - a;
          if (trans == 0.0) break;
        }
        for (int ch = 0; ch < 3; ++ch) {
          sum[ch] += c[ch] + trans * bg[ch];
          stored[4 * s + ch] = framebuffer_store(enc, ch, float(c[ch] + trans * bg[ch]));
        }
        stored[4 * s + 3] = 1.0f;
      }
      float* o = img.at(x, y);
      if (fixed) {  // resolved as blend resolves its framebuffer (colour_buffer_image)
        float rgb[3];
        framebuffer_resolve_pixel(enc, stored, spp, rgb);
        for (int ch = 0; ch < 3; ++ch) o[ch] = framebuffer_light(enc, rgb[ch]);
      } else {
        for (int ch = 0; ch < 3; ++ch) o[ch] = float(sum[ch] / spp);
      }
    }
  });
  return img;
}

size_t ReferenceModel::state_bytes() const {
  return entries_.capacity() * sizeof(Entry) + z_.capacity() * sizeof(float) + heads_.tiles() * sizeof(HeadTile) +
         heads_.directory_bytes() + (base_ ? base_->store().state_bytes() : 0);
}

std::unique_ptr<FunctionalModel> make_functional_model(const TraceHeader& h, const GoldenConfig& cfg, int threads) {
  if (const char* err = validate(cfg.numerics)) throw UserError(err);
  if (cfg.method == Method::kReference) return std::make_unique<ReferenceModel>(h);
  return std::make_unique<StochasticModel>(h, cfg, threads > 0 ? threads : host_threads());
}

}  // namespace ropsim
