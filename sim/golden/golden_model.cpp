#include "golden_model.h"

#include <algorithm>
#include <cmath>

#include "alpha_ref.h"
#include "depth.h"
#include "half.h"
#include "hilbert.h"
#include "method_kernels.h"
#include "opacity.h"
#include "random_hash.h"
#include "sort_order.h"

namespace ropsim {

namespace {
struct MethodName {
  Method m;
  const char* name;
};
constexpr MethodName kMethods[] = {{Method::kLk, "lk"},         {Method::kEnderton, "enderton"},
                                   {Method::kNaive, "naive"},   {Method::kA2c, "a2c"},
                                   {Method::kOpaque, "opaque"}, {Method::kReference, "reference"}};

}  // namespace

const char* to_string(Method m) {
  for (const auto& x : kMethods)
    if (x.m == m) return x.name;
  return "?";
}

bool parse_method(const std::string& s, Method& out) {
  for (const auto& x : kMethods)
    if (s == x.name) { out = x.m; return true; }
  return false;
}

const std::vector<std::string>& method_names() {
  static const std::vector<std::string> v = [] {
    std::vector<std::string> r;
    for (const auto& x : kMethods) r.push_back(x.name);
    return r;
  }();
  return v;
}

// ------------------------------------------------------------ StochasticModel

StochasticModel::StochasticModel(const TraceHeader& h, const GoldenConfig& cfg)
    : FunctionalModel(h), cfg_(cfg), store_(h, cfg.method == Method::kLk), hilbert_n_(hilbert_side(h.width, h.height)),
      alpha_one_(uint64_t{1} << cfg.numerics.alpha_bits),
      tracker_bytes_((h.spp + cfg.numerics.surface_id_bits + 7) / 8), memo_(cfg.numerics.alpha_bits) {
  switch (cfg.method) {
    case Method::kLk: draw_fn_ = &StochasticModel::draw_lk; break;
    case Method::kEnderton: draw_fn_ = &StochasticModel::draw_enderton; break;
    case Method::kNaive: draw_fn_ = &StochasticModel::draw_naive; break;
    case Method::kA2c: draw_fn_ = &StochasticModel::draw_a2c; break;
    case Method::kOpaque: draw_fn_ = &StochasticModel::draw_opaque; break;
    case Method::kReference: throw std::logic_error("StochasticModel cannot run the reference method");
  }
  for (int i = 0; i < h.spp; ++i) {
    offset_x_[size_t(i)] = sample_offset(h.positions[size_t(i)].x);
    offset_y_[size_t(i)] = sample_offset(h.positions[size_t(i)].y);
  }
  a2c_prefix_ = a2c_prefix_table(h.spp);
}

inline void StochasticModel::sample_depths(const Fragment& f, float* z) const {
  if (header_.depth_mode == DepthMode::kPlane) {
    for (uint64_t m = f.coverage; m; m &= m - 1) {
      const int i = __builtin_ctzll(m);
      z[i] = plane_depth(f.z0, f.dzdx, f.dzdy, offset_x_[size_t(i)], offset_y_[size_t(i)]);
    }
  } else {
    fragment_sample_depths(header_, f, z);
  }
}

inline void StochasticModel::count_written(uint32_t n) {
  counters_.samples_written += n;
  counters_.depth_bytes_written += 4u * n;  // binary32 depth
  counters_.color_bytes_written += 6u * n;  // RGB binary16
}

void StochasticModel::draw(const Fragment& f) {
  ++counters_.fragments;
  const int covered = __builtin_popcountll(f.coverage);
  counters_.samples_tested += covered;
  counters_.depth_bytes_read += 4u * covered;
  (this->*draw_fn_)(f);
  counters_.tiles_touched = store_.tiles();
}

// LK 2011 Figure 7, line for line.
void StochasticModel::draw_lk(const Fragment& f) {
  const Numerics& num = cfg_.numerics;
  PixelRef p = store_.pixel(f.x, f.y);
  float z[64];
  sample_depths(f, z);
  // Lines 1-3: depth test first.
  uint64_t S = 0;
  for (uint64_t m = f.coverage; m; m &= m - 1) {  // branch-free: pass/fail is data-dependent
    const int i = __builtin_ctzll(m);
    S |= uint64_t{depth_passes(z[i], p.depth[i])} << i;
  }
  const int m = __builtin_popcountll(S);
  counters_.samples_depth_passed += m;
  counters_.tracker_bytes_read += tracker_bytes_;
  if (!m) return;  // nothing survives: the tracker is unchanged (line 18 sets no bit)
  // Lines 4-8: surface tracking.
  const TrackResult tr = track_surface(*p.tracker, S, num.surface_id_bits);
  counters_.surface_id_changes += tr.new_surface;
  // Line 9: sort the surviving samples by the depth already stored.
  uint8_t order[64];
  sort_by_stored_depth(p.depth, S, order);
  counters_.sorts += m > 1;
  // Lines 10-17: opacity test against CalcAlphaRef(n, pixelId, surfaceId).
  const uint64_t pixel_id = hilbert_xy2d(hilbert_n_, f.x, f.y);
  const uint64_t a = fixed_alpha(f.alpha);
  const uint16_t* rgb16 = half_color(f.rgb);
  uint32_t refs[64];
  calc_alpha_refs(tr.n, m, pixel_id, tr.surface_id, uint32_t(header_.spp), num.hash_bits, refs);
  uint32_t written = 0;
  for (int j = 0; j < m; ++j) {
    const int i = order[j];
    if (opacity_passes(a, num.alpha_bits, refs[j], num.hash_bits)) {
      p.write_sample(i, z[i], rgb16);
      ++written;
    }
  }
  // Line 18.
  track_commit(*p.tracker, S);
  counters_.tracker_bytes_written += tracker_bytes_;
  counters_.samples_opacity_passed += written;
  count_written(written);
}

// Enderton et al. 2010 with the depth test first (as LK compare against):
// R = floor(alpha * |S'| + xi) samples chosen uniformly among the survivors S'.
void StochasticModel::draw_enderton(const Fragment& f) {
  const Numerics& num = cfg_.numerics;
  PixelRef p = store_.pixel(f.x, f.y);
  float z[64];
  sample_depths(f, z);
  int list[64], m = 0;
  for (uint64_t c = f.coverage; c; c &= c - 1) {
    const int i = __builtin_ctzll(c);
    if (depth_passes(z[i], p.depth[i])) list[m++] = i;
  }
  counters_.samples_depth_passed += m;
  if (!m) return;
  const uint64_t key = fragment_key(cfg_.seed, f.draw_id, f.prim_id, f.x, f.y);
  const uint32_t r = enderton_count(fixed_alpha(f.alpha), num.alpha_bits, uint32_t(m), key);
  enderton_pick(list, uint32_t(m), r, key);
  const uint16_t* rgb16 = half_color(f.rgb);
  for (uint32_t j = 0; j < r; ++j) p.write_sample(list[j], z[list[j]], rgb16);
  counters_.samples_opacity_passed += r;
  count_written(r);
}

// Naive stochastic transparency (LK §1.1): an independent random reference per sample.
void StochasticModel::draw_naive(const Fragment& f) {
  const Numerics& num = cfg_.numerics;
  PixelRef p = store_.pixel(f.x, f.y);
  float z[64];
  sample_depths(f, z);
  const uint64_t key = fragment_key(cfg_.seed, f.draw_id, f.prim_id, f.x, f.y);
  const uint64_t a = fixed_alpha(f.alpha);
  const uint16_t* rgb16 = half_color(f.rgb);
  uint32_t passed = 0, written = 0;
  for (uint64_t c = f.coverage; c; c &= c - 1) {
    const int i = __builtin_ctzll(c);
    if (!depth_passes(z[i], p.depth[i])) continue;
    ++passed;
    if (opacity_passes(a, num.alpha_bits, fragment_random(key, uint32_t(i) + 1), 32)) {
      p.write_sample(i, z[i], rgb16);
      ++written;
    }
  }
  counters_.samples_depth_passed += passed;
  counters_.samples_opacity_passed += written;
  count_written(written);
}

// Alpha-to-coverage as today's hardware: k = floor(alpha * spp + dither) samples
// from a fixed order, dithered with a 4x4 Bayer threshold per pixel; the same
// alpha always gives the same samples in a pixel (static assignment).
void StochasticModel::draw_a2c(const Fragment& f) {
  PixelRef p = store_.pixel(f.x, f.y);
  float z[64];
  sample_depths(f, z);
  const uint32_t k = a2c_sample_count(fixed_alpha(f.alpha), cfg_.numerics.alpha_bits, header_.spp, f.x, f.y);
  const uint64_t mask = f.coverage & a2c_prefix_[k];
  const uint16_t* rgb16 = half_color(f.rgb);
  uint32_t written = 0;
  for (uint64_t c = mask; c; c &= c - 1) {
    const int i = __builtin_ctzll(c);
    if (depth_passes(z[i], p.depth[i])) {
      p.write_sample(i, z[i], rgb16);
      ++written;
    }
  }
  counters_.samples_opacity_passed += __builtin_popcountll(mask);
  counters_.samples_depth_passed += written;
  count_written(written);
}

void StochasticModel::draw_opaque(const Fragment& f) {
  PixelRef p = store_.pixel(f.x, f.y);
  float z[64];
  sample_depths(f, z);
  const uint16_t* rgb16 = half_color(f.rgb);
  uint32_t written = 0;
  for (uint64_t c = f.coverage; c; c &= c - 1) {
    const int i = __builtin_ctzll(c);
    if (depth_passes(z[i], p.depth[i])) {
      p.write_sample(i, z[i], rgb16);
      ++written;
    }
  }
  counters_.samples_depth_passed += written;
  counters_.samples_opacity_passed += written;
  count_written(written);
}

Image StochasticModel::resolve() const { return store_.resolve(); }

size_t StochasticModel::state_bytes() const { return store_.state_bytes(); }

// ------------------------------------------------------------ ReferenceModel

ReferenceModel::ReferenceModel(const TraceHeader& h) : FunctionalModel(h), heads_(h.width, h.height) {}

void ReferenceModel::draw(const Fragment& f) {
  ++counters_.fragments;
  const int covered = __builtin_popcountll(f.coverage);
  counters_.samples_tested += covered;
  HeadTile& t = heads_.get(f.x, f.y, [](uint32_t, uint32_t) {
    auto ht = std::make_unique<HeadTile>();
    ht->head.fill(-1);
    return ht;
  });
  int64_t& head = t.head[pixel_in_tile(f.x, f.y)];
  Entry e;
  e.coverage = f.coverage;
  e.z_offset = z_.size();
  e.rgb = f.rgb;
  e.alpha = f.alpha;
  e.seq = head < 0 ? 0 : entries_[size_t(head)].seq + 1;
  e.next = head;
  float z[64];
  fragment_sample_depths(header_, f, z);
  for (uint64_t m = f.coverage; m; m &= m - 1) z_.push_back(z[__builtin_ctzll(m)]);
  head = int64_t(entries_.size());
  entries_.push_back(e);
  counters_.tiles_touched = heads_.tiles();
}

Image ReferenceModel::resolve() const {
  Image img;
  img.width = header_.width;
  img.height = header_.height;
  img.rgb.resize(size_t(img.width) * img.height * 3);
  for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = header_.clear_color[i % 3];
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
      for (int s = 0; s < spp; ++s) {
        auto& L = layers[s];
        // Nearest first; at equal depth the later fragment is in front, as the
        // LESS_EQUAL depth test of the stochastic methods decides.
        std::sort(L.begin(), L.end(), [](const Layer& a, const Layer& b) {
          return a.z != b.z ? a.z < b.z : a.seq > b.seq;
        });
        double trans = 1.0, c[3] = {0, 0, 0};
        for (const Layer& l : L) {
          const double a = l.e->alpha;
          for (int ch = 0; ch < 3; ++ch) c[ch] += trans * a * l.e->rgb[ch];
          trans *= 1.0 - a;
          if (trans == 0.0) break;
        }
        for (int ch = 0; ch < 3; ++ch) sum[ch] += c[ch] + trans * header_.clear_color[ch];
      }
      float* o = img.at(x0 + (p & 7), y0 + (p >> 3));
      for (int ch = 0; ch < 3; ++ch) o[ch] = float(sum[ch] / spp);
    }
  });
  return img;
}

size_t ReferenceModel::state_bytes() const {
  return entries_.capacity() * sizeof(Entry) + z_.capacity() * sizeof(float) + heads_.tiles() * sizeof(HeadTile) +
         heads_.directory_bytes();
}

std::unique_ptr<FunctionalModel> make_functional_model(const TraceHeader& h, const GoldenConfig& cfg) {
  if (const char* err = validate(cfg.numerics)) throw std::invalid_argument(err);
  if (cfg.method == Method::kReference) return std::make_unique<ReferenceModel>(h);
  return std::make_unique<StochasticModel>(h, cfg);
}

}  // namespace ropsim
