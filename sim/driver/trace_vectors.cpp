// RTL test vectors captured from a trace: the calls the golden model makes
// of each unit while it replays the trace.
#include <fmt/format.h>

#include <algorithm>
#include <cstring>
#include <iterator>
#include <sstream>
#include <stdexcept>

#include "rtl_models/algo/alpha_ref.h"
#include "rtl_models/algo/depth.h"
#include "rtl_models/algo/half.h"
#include "rtl_models/algo/hilbert.h"
#include "rtl_models/algo/opacity.h"
#include "rtl_models/algo/random_hash.h"
#include "rtl_models/algo/sort_order.h"
#include "rtl_models/algo/tracker.h"
#include "rtl_models/golden/golden_model.h"
#include "sim/driver/vector_rows.h"
#include "sim/driver/vectors.h"
#include "traces/raster/sample_patterns.h"
#include "util/errors.h"

namespace ropsim {

using namespace vector_rows;

namespace {

/// Formats each captured call of one unit as its row (or hex word) and
/// hands the text to the sink in pieces of about a megabyte.
class VectorCapture : public RopObserver {
 public:
  VectorCapture(const std::string& unit, const TraceHeader& h, const TraceVectorRequest& req,
                const std::function<void(std::string_view)>& write)
      : unit_(unit), spp_(h.spp), req_(req), hex_(req.format == "hex"), write_(write) {}

  void depth_tested(const FragWork& w) override {
    if (unit_ != "depth-test" || !keep(w)) return;
    const Fragment& f = *w.f;
    emit(depth_test_row(spp_, w.covered, f.z0, f.dzdx, f.dzdy, w.px.depth, w.z, w.survivors));
  }
  void tracked(const FragWork& w, const TrackerState& before, int surface_id_bits) override {
    if (unit_ == "tracker" && keep(w))
      emit(tracker_row(spp_, surface_id_bits, before, w.survivors, w.lk.track, *w.px.tracker));
  }
  void sorted(const FragWork& w) override {
    if (unit_ == "sorter" && keep(w)) emit(sorter_row(spp_, w.survivors, w.px.depth, w.lk.order, int(w.m)));
  }
  void referenced(const FragWork& w, uint32_t hilbert_n, uint64_t pixel_id, int hash_bits) override {
    if (!keep(w)) return;
    if (unit_ == "hilbert") emit(hilbert_row(__builtin_ctz(hilbert_n), w.f->x, w.f->y, pixel_id));
    if (unit_ != "alpha-ref") return;
    for (uint32_t j = 0; j < w.m; ++j) {
      const uint32_t sample_id = w.lk.track.n + j;  // the running index of LK Fig. 7 line 11
      emit(alpha_ref_row(sample_id, pixel_id, w.lk.track.surface_id, uint32_t(spp_), hash_bits,
                         alpha_ref_index(sample_id, pixel_id, uint32_t(spp_), hash_bits), w.lk.ref[j]));
    }
  }
  void opacity_tested(const FragWork& w, uint64_t a_fixed, int alpha_bits, uint32_t ref, int hash_bits,
                      bool passed) override {
    if (unit_ == "opacity" && keep(w)) emit(opacity_row(alpha_bits, hash_bits, a_fixed, ref, passed));
  }

  uint64_t rows() const { return rows_; }
  void start() { buf_ = hex_ ? hex_comment(unit_) : header_of(unit_); }
  void finish() {
    if (!buf_.empty()) write_(buf_);
    buf_.clear();
  }

 private:
  static std::string header_of(const std::string& unit) {
    if (unit == "alpha-ref") return kAlphaRefHeader;
    if (unit == "tracker") return kTrackerHeader;
    if (unit == "sorter") return kSorterHeader;
    if (unit == "depth-test") return kDepthTestHeader;
    if (unit == "opacity") return kOpacityHeader;
    return kHilbertHeader;
  }
  bool keep(const FragWork& w) const {
    const Fragment& f = *w.f;
    if (req_.draw && f.draw_id != *req_.draw) return false;
    if (const auto& b = req_.window) return f.x >= b->x0 && f.x <= b->x1 && f.y >= b->y0 && f.y <= b->y1;
    return true;
  }
  void emit(const std::string& row) {
    ++rows_;
    if (hex_)
      buf_ += hex_word(unit_, row.substr(0, row.size() - 1)) + "\n";
    else
      buf_ += row;
    if (buf_.size() >= (size_t{1} << 20)) finish();
  }
  std::string unit_;
  int spp_;
  const TraceVectorRequest& req_;
  bool hex_;
  const std::function<void(std::string_view)>& write_;
  std::string buf_;
  uint64_t rows_ = 0;
};

/// Does method m's ROP call unit's rule? Empty if so, else why not.
std::string calls_unit(Method m, const std::string& unit) {
  const MethodTraits& t = traits(selection_of(m));
  const char* name = to_string(m);
  if (!traits(m).pipeline) return std::string("the ") + name + " method has no ROP pipeline";
  if (unit == "depth-test" && m == Method::kSlab)
    return "slab has no per-sample depth test (its layers hold the depth)";
  if (unit == "depth-test" && m == Method::kBlend)
    return "blend tests depth with each draw's own function; the depth-test unit's rule (rop_depth_compare) is "
           "LEQUAL";
  if ((unit == "tracker" && !t.tracker) || (unit == "sorter" && !t.sorter) ||
      ((unit == "alpha-ref" || unit == "hilbert") && selection_of(m) != Method::kLk) ||
      (unit == "opacity" && selection_of(m) != Method::kLk && m != Method::kNaive))
    return std::string(name) + " never calls the " + unit + " unit (lk and its variants do" +
           (unit == "opacity" ? ", and naive" : "") + ")";
  return "";
}

}  // namespace

const std::vector<std::string>& trace_vector_units() {
  static const std::vector<std::string> u = {"alpha-ref", "tracker", "sorter", "depth-test", "opacity", "hilbert"};
  return u;
}

uint64_t make_trace_vectors(const std::string& unit, const TraceVectorRequest& req,
                            const std::function<void(std::string_view)>& write) {
  const auto& units = trace_vector_units();
  if (std::find(units.begin(), units.end(), unit) == units.end()) {
    std::string known;
    for (const auto& u : units) known += (known.empty() ? "" : ", ") + u;
    throw VectorError("--trace captures the calls of " + known + ", not " + unit);
  }
  if (req.format != "csv" && req.format != "hex") throw VectorError("format must be csv or hex");
  if (const std::string why = calls_unit(req.method.method, unit); !why.empty())
    throw VectorError(unit + " vectors of " + to_string(req.method.method) + ": " + why);
  if (const auto& b = req.window; b && (b->x0 > b->x1 || b->y0 > b->y1))
    throw VectorError("--window: x0 > x1 or y0 > y1");
  auto src = open_fragments(req.input);
  const TraceHeader h = src->header();
  if (unit == "depth-test") {
    // The depth-test vectors hold a plane and the standard sample positions.
    if (h.depth_mode != DepthMode::kPlane)
      throw VectorError(req.input.describe() +
                        ": the trace stores per-sample depths; depth-test vectors take a plane (z0, dzdx, dzdy)");
    const auto standard = standard_sample_positions(h.spp);
    for (int i = 0; i < h.spp; ++i)
      if (h.positions[size_t(i)].x != standard[size_t(i)].x || h.positions[size_t(i)].y != standard[size_t(i)].y)
        throw VectorError(req.input.describe() + ": sample " + std::to_string(i) +
                          "'s position is not the standard one of " + std::to_string(h.spp) +
                          " spp, which the depth-test vectors assume");
  }
  StochasticModel model(h, req.method, 1);
  VectorCapture capture(unit, h, req, write);
  model.set_rop_observer(&capture);
  capture.start();
  std::vector<Fragment> batch(4096);
  for (int pass = 0; pass < model.passes(); ++pass) {
    if (pass > 0) src = open_fragments(req.input);  // every pass replays the input
    model.begin_pass(pass);
    for (;;) {
      size_t n = 0;
      while (n < batch.size() && src->next(batch[n])) ++n;
      if (n == 0) break;
      model.draw_batch(batch.data(), n);
    }
  }
  capture.finish();
  return capture.rows();
}

}  // namespace ropsim
