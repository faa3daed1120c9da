#include "golden_model.h"

#include <algorithm>
#include <cmath>

namespace ropsim {

StochasticModel::StochasticModel(const TraceHeader& h, const GoldenConfig& cfg) : FunctionalModel(h), rop_(h, cfg) {}

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
}

void ReferenceModel::draw(const Fragment& f) {
  ++counters_.fragments;
  const int covered = __builtin_popcountll(f.coverage);
  counters_.samples_tested += covered;
  HeadTile& t = heads_.get(f.x, f.y, [this](uint32_t, uint32_t) {
    mem_.add(sizeof(HeadTile), "the A-buffer reference's fragment lists");
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
  setup_.sample_depths(f, f.coverage, z);
  grow_for(z_, size_t(covered), mem_);
  grow_for(entries_, 1, mem_);
  for (uint64_t m = f.coverage; m; m &= m - 1) z_.push_back(z[__builtin_ctzll(m)]);
  head = int64_t(entries_.size());
  entries_.push_back(e);
  counters_.tiles_touched = heads_.tiles();
}

Image ReferenceModel::resolve() const {
  Image img(header_.width, header_.height, {header_.clear_color[0], header_.clear_color[1], header_.clear_color[2]});
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
        std::sort(L.begin(), L.end(),
                  [](const Layer& a, const Layer& b) { return a.z != b.z ? a.z < b.z : a.seq > b.seq; });
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
