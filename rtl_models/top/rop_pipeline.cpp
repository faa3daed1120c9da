#include "rtl_models/top/rop_pipeline.h"

#include "rtl_models/units/alpha_ref_gen.h"
#include "rtl_models/units/blend_unit.h"
#include "rtl_models/units/coverage_tracker.h"
#include "rtl_models/units/depth_test.h"
#include "rtl_models/units/pixel_ordering.h"
#include "rtl_models/units/sample_sorter.h"
#include "rtl_models/units/writeback.h"
#include "util/errors.h"

namespace ropsim {

RopPipeline::RopPipeline(const sc_core::sc_module_name& name, std::unique_ptr<FragmentSource> input, FunctionalRop& rop,
                         LineSet& in_dram, const HwConfig& hw)
    : sc_module(name),
      hw_(hw),
      clk_(hw.clock.frequency_ghz),
      input_(std::move(input)),
      rop_(rop),
      retirement_(pool_),
      amap_(input_->header().width, input_->header().spp, rop_.setup().tracker_bytes, hw.cache.line_bytes,
            rop_.setup().bytes.stored, rop_.setup().slab_bytes),
      dram_(hw.dram),
      in_dram_(in_dram) {
  const MethodTraits& mt = rop_.traits();
  const bool blend_pass = is_blend_pass(rop_.pass());
  const TraceHeader& header = rop_.header();
  sched_ = std::make_unique<Scheduler>("scheduler", clk_);
  const int spp = header.spp;
  const uint32_t n_rops = hw.distributor.rop_units;

  TokenFifo& src_out = make_fifo("source_to_distributor", hw.source.fifo_depth, 1);
  source_ = &add("trace_source", -1,
                 std::make_unique<TraceSource>("trace_source", clk_, *input_, rop_, pool_, hw.source, src_out,
                                               RopOwnership(hw.distributor, header.width)));
  std::vector<TokenFifo*> rop_in;
  for (uint32_t r = 0; r < n_rops; ++r)
    rop_in.push_back(
        &make_fifo("rop" + std::to_string(r) + ".input", hw.distributor.fifo_depth, hw.distributor.latency_cycles));
  auto& dist = add("distributor", -1,
                   std::make_unique<Distributor>("distributor", clk_, hw.distributor, header.width, src_out, rop_in));
  src_out.connect(source_, &dist);

  for (uint32_t r = 0; r < n_rops; ++r) {
    const std::string p = "rop" + std::to_string(r) + ".";  // FIFO names
    const std::string u = "rop" + std::to_string(r) + "_";  // module names ('.' is the hierarchy separator)
    const int ri = int(r);
    caches_.push_back(std::make_unique<RopCache>(hw.cache, dram_, in_dram_, &posted_, r));
    RopCache& cache = *caches_.back();

    TokenFifo& ord_out = make_fifo(p + "ordering_to_depth", hw.ordering.fifo_depth, hw.ordering.latency_cycles);
    auto& ord =
        add("pixel_ordering", ri,
            std::make_unique<PixelOrdering>((u + "pixel_ordering").c_str(), clk_, hw.ordering, *rop_in[r], ord_out));
    rop_in[r]->connect(&dist, &ord);
    retirement_.attach(r, &ord);

    TokenFifo& dt_out = make_fifo(p + "depth_out", hw.depth_test.fifo_depth, hw.depth_test.latency_cycles);
    Unit* prev = &add("depth_test", ri,
                      std::make_unique<DepthTest>((u + "depth_test").c_str(), clk_, rop_, retirement_, amap_,
                                                  hw.depth_test, cache, ord_out, dt_out));
    ord_out.connect(&ord, prev);
    TokenFifo* link = &dt_out;

    if (blend_pass) {  // depth test (not writing) -> blend
      Unit* bl = &add(
          "blend", ri,
          std::make_unique<BlendUnit>((u + "blend").c_str(), clk_, rop_, retirement_, amap_, hw.blend, cache, *link));
      link->connect(prev, bl);
      continue;
    }
    if (mt.tracker) {
      TokenFifo& tr_out = make_fifo(p + "tracker_to_sorter", hw.tracker.fifo_depth, hw.tracker.latency_cycles);
      Unit* tr = &add(
          "coverage_tracker", ri,
          std::make_unique<CoverageTracker>((u + "coverage_tracker").c_str(), clk_, rop_, hw.tracker, *link, tr_out));
      link->connect(prev, tr);
      prev = tr;
      link = &tr_out;
    }
    if (mt.sorter) {
      auto algo = make_sorter(hw.sorter.kind, spp);
      TokenFifo& so_out = make_fifo(p + "sorter_to_alpha_ref", hw.sorter.fifo_depth, algo->latency_cycles(spp));
      Unit* so = &add(
          "sample_sorter", ri,
          std::make_unique<SampleSorter>((u + "sample_sorter").c_str(), clk_, rop_, std::move(algo), *link, so_out));
      link->connect(prev, so);
      prev = so;
      link = &so_out;
    }
    if (mt.reference) {
      const uint32_t worst = hw.alpha_ref.pipeline_depth + ceil_div(uint32_t(spp) + 1, hw.alpha_ref.lanes) - 1;
      TokenFifo& ar_out = make_fifo(p + "alpha_ref_to_writeback", hw.alpha_ref.fifo_depth, worst);
      Unit* ar =
          &add("alpha_ref_gen", ri,
               std::make_unique<AlphaRefGen>((u + "alpha_ref_gen").c_str(), clk_, rop_, hw.alpha_ref, *link, ar_out));
      link->connect(prev, ar);
      prev = ar;
      link = &ar_out;
    }
    Unit* wb = &add("writeback", ri,
                    std::make_unique<Writeback>((u + "writeback").c_str(), clk_, rop_, retirement_, amap_, hw.writeback,
                                                cache, *link));
    link->connect(prev, wb);
  }
  pool_.reserve(token_bound());
}

size_t RopPipeline::token_bound() const {
  // A fragment in flight is in a FIFO, in a pixel ordering window or waiting
  // in a depth test; and one more the trace source holds.
  size_t n = 1 + size_t(hw_.distributor.rop_units) * (hw_.ordering.window + hw_.depth_test.max_outstanding);
  for (const auto& f : fifos_) n += f->capacity();
  return n;
}

void RopPipeline::log_to(IntervalLog* log) {
  dram_.log_to(log);
  for (auto& c : caches_) c->log_to(log);
  for (auto& u : units_) u.unit->log_to(log, log ? log->kind(u.kind) : -1);
}

void RopPipeline::attribute_to(Attribution* attr) {
  dram_.attribute_to(attr);
  for (auto& c : caches_) c->attribute_to(attr);
  for (auto& u : units_) u.unit->attribute_to(attr && attr->tiles() ? attr : nullptr);
}

void RopPipeline::set_decoupled(bool on) {
  for (const auto& u : units_)
    if (auto* d = dynamic_cast<DecoupledUnit*>(u.unit)) d->set_decoupled(on);
}

RopPipeline::~RopPipeline() = default;

TokenFifo& RopPipeline::make_fifo(const std::string& name, uint32_t depth, uint32_t producer_latency) {
  fifos_.push_back(std::make_unique<TokenFifo>(name, depth + producer_latency, clk_));
  return *fifos_.back();
}

template <class U>
U& RopPipeline::add(const std::string& kind, int rop, std::unique_ptr<U> u) {
  U& ref = *u;
  units_.push_back(UnitEntry{kind, rop, u.get()});
  owned_.push_back(std::move(u));
  return ref;
}

std::vector<TokenFifo*> RopPipeline::fifos() const {
  std::vector<TokenFifo*> v;
  for (const auto& f : fifos_) v.push_back(f.get());
  return v;
}

void RopPipeline::trace_to(Waveform& wave, const std::string& prefix) {
  std::vector<std::string> states;
  for (int a = 0; a < kActivities; ++a) states.push_back(to_string(Activity(a)));
  // Unit by unit in pipeline order, each after the FIFOs it reads, under its
  // ROP's scope (a shared unit: its own).
  for (const auto& u : units_) {
    const std::string scope = prefix + (u.rop >= 0 ? "rop" + std::to_string(u.rop) : u.kind);
    for (const auto& f : fifos_) {
      if (f->consumer() != u.unit) continue;
      const std::string& n = f->name();  // "rop0.ordering_to_depth", "source_to_distributor"
      const auto dot = n.rfind('.');
      f->trace_to(&wave, wave.add_occupancy(scope, "fifo_" + (dot == std::string::npos ? n : n.substr(dot + 1))));
    }
    u.unit->trace_to(&wave, wave.add_state(scope, u.kind, states));
  }
  dram_.trace_to(wave, prefix + "dram");
}

void RopPipeline::compress_with(CompressionModel* comp) {
  comp_ = comp;
  if (comp) comp->set_dram(&dram_);
  for (auto& c : caches_) c->compress_with(comp);
}

uint64_t RopPipeline::run() {
  sc_core::sc_start();
  if (source_->error()) std::rethrow_exception(source_->error());
  // SystemC stops when no event is pending: that must be because every
  // fragment has retired, never because a wake-up was lost.
  if (!source_->done() || retirement_.retired() != source_->produced()) {
    std::string held;
    for (const auto& f : fifos_)
      if (!f->empty()) held += "; " + f->name() + " holds " + std::to_string(f->size());
    throw InternalError("every fragment retires before the simulation ends: the cycle model stalled at cycle " +
                        std::to_string(clk_.now()) + ", " + std::to_string(retirement_.retired()) + " of " +
                        std::to_string(source_->produced()) + " fragments retired" +
                        (source_->done() ? "" : " and the trace source is not done") + held + " (a lost wake-up)");
  }
  // The last retirement, not SystemC's final time: decoupled units close their
  // outputs without SystemC time passing, so that differs between the modes.
  pipeline_cycles_ = retirement_.last_cycle();
  uint64_t end = pipeline_cycles_;
  for (auto& c : caches_) end = std::max(end, c->flush(pipeline_cycles_));
  if (comp_) end = std::max(end, comp_->flush(pipeline_cycles_));  // the state bits after the data
  if (dram_.attributing()) dram_.settle_attribution();
  total_cycles_ = std::max(end, dram_.stats().last_completion);
  for (const auto& u : units_) {
    u.unit->close_accounting(total_cycles_);
    u.unit->close_attribution();
  }
  return total_cycles_;
}

}  // namespace ropsim
