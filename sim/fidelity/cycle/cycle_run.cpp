#include "sim/fidelity/cycle/cycle_run.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "rtl_models/algo/depth.h"
#include "rtl_models/functional/compressibility.h"
#include "rtl_models/functional/pass_loop.h"
#include "rtl_models/memory/compression_model.h"
#include "rtl_models/memory/line_set.h"
#include "rtl_models/top/memory_estimate.h"
#include "rtl_models/top/rop_pipeline.h"
#include "rtl_models/top/sim_context.h"
#include "rtl_models/top/surface_compression.h"
#include "util/errors.h"
#include "util/memory_budget.h"
#include "util/output_file.h"

namespace ropsim {

std::vector<ResourceBound> cycle_bounds(const CycleStats& s) {
  // An instance is its kind and ROP: a multi-pass method has one per pass,
  // and the passes run one after another, so their busy cycles add up.
  struct Instance {
    std::string kind;
    int rop;
    uint64_t busy;
  };
  std::vector<Instance> inst;
  for (const auto& u : s.units) {
    const uint64_t busy = u.stats.cycles[size_t(Activity::kBusy)];
    auto it =
        std::find_if(inst.begin(), inst.end(), [&](const Instance& i) { return i.kind == u.kind && i.rop == u.rop; });
    if (it == inst.end())
      inst.push_back({u.kind, u.rop, busy});
    else
      it->busy += busy;
  }
  std::vector<ResourceBound> b;
  for (const Instance& i : inst) {  // the units' order: the pipeline's
    auto it = std::find_if(b.begin(), b.end(), [&](const ResourceBound& r) { return r.name == i.kind; });
    if (it == b.end())
      b.push_back({i.kind, ResourceBound::Kind::kThroughput, double(i.busy)});
    else
      it->cycles = std::max(it->cycles, double(i.busy));
  }
  b.push_back({"dram", ResourceBound::Kind::kBandwidth, double(s.dram.max_channel_service)});
  return b;
}

Bottleneck classify_bottleneck(const CycleStats& s) {
  return classify_bottleneck(cycle_bounds(s), double(s.total_cycles));
}

const std::vector<StatDesc>& tile_map_descs() {
  static const std::vector<StatDesc> d = {
      {"tile_cycles", "cycles",
       "the cycles charged to the tile: each retirement charges the cycles since the previous one to its fragment's "
       "tile (sum: timing.pipeline_cycles)"},
      {"tile_busy", "cycles",
       "cycles the units spent busy on the tile's fragments (each unit charges its cycles to the tile of the fragment "
       "it took last; sum: timing.units[].cycles.busy, every unit)"},
      {"tile_input_starved", "cycles",
       "the same, waiting for input (sum: timing.units[].cycles.input_starved, every unit)"},
      {"tile_output_blocked", "cycles",
       "the same, waiting for space in the FIFO behind (sum: timing.units[].cycles.output_blocked, every unit)"},
      {"tile_pixel_hazard", "cycles",
       "the same, pixel ordering waiting on pixels in flight (sum: timing.units[].cycles.pixel_hazard)"},
      {"tile_memory", "cycles",
       "the same, waiting for the ROP cache or DRAM (sum: timing.units[].cycles.memory, every unit)"},
      {"tile_cache_misses", "accesses",
       "ROP cache read and write misses of the tile's fragments (sum: timing.cache.misses)"},
  };
  return d;
}

const std::vector<uint64_t>& tile_map(const Attribution& a, size_t i) {
  static constexpr Activity kByMap[] = {Activity::kBusy, Activity::kStarved, Activity::kBlocked, Activity::kHazard,
                                        Activity::kMemory};
  if (i == 0) return a.retire_cycles();
  if (i <= 5) return a.unit_cycles(int(kByMap[i - 1]));
  invariant(i == 6, "a tile map index is below tile_map_descs().size()");
  return a.cache_misses();
}

namespace {

void add_dram(DramStats& a, const DramStats& b) {
  for (size_t i = 0; i < size_t(kBuffers); ++i) {
    a.bytes_read[i] += b.bytes_read[i];
    a.bytes_written[i] += b.bytes_written[i];
  }
  a.reads += b.reads;
  a.writes += b.writes;
  a.row_hits += b.row_hits;
  a.row_misses += b.row_misses;
  a.busy_cycles += b.busy_cycles;
  a.max_channel_busy += b.max_channel_busy;  // passes run one after another
  a.max_channel_service += b.max_channel_service;
}

}  // namespace

CycleRun run_cycle(const InputSpec& in, const GoldenConfig& method, const HwConfig& hw, const CycleOptions& opt) {
  return run_cycle([&in] { return open_fragments(in); }, method, hw, opt);
}

CycleRun run_cycle(const std::function<std::unique_ptr<FragmentSource>()>& open_input, const GoldenConfig& method,
                   const HwConfig& hw, const CycleOptions& opt) {
  if (method.method == Method::kReference)
    throw UserError("the reference method (A-buffer) has no ROP pipeline; use --fidelity functional");
  if (const char* err = validate(method.numerics)) throw UserError(err);
  validate_hw_config(hw);
  const auto t0 = std::chrono::steady_clock::now();
  CycleRun run;
  // The functional ROP and the lines DRAM holds outlive the passes; each pass
  // is one pipeline in its own SystemC context over a fresh read of the input.
  std::unique_ptr<FragmentSource> input = open_input();
  run.header = input->header();
  // The model's structures, charged to --memory-limit before any is built
  // (memory_estimate.h); a design that does not fit is refused here.
  const MemoryEstimate estimate =
      estimate_memory(hw, MemoryShape{run.header.width, run.header.height, run.header.spp, method.method});
  check_model_memory(hw, estimate);
  BudgetShare model_memory;
  model_memory.add(estimate.total_bytes, "the cycle model's structures");
  auto rop = std::make_unique<FunctionalRop>(run.header, on_design(method, hw.compression.setup()));
  LineSet in_dram(hw.cache.line_bytes);
  // Surface compression and Hi-Z: the stored state bits and Hi-Z bounds
  // outlive the passes, like the lines DRAM holds.
  const SurfaceCompression comp = compress_surfaces(hw, run.header, *rop);
  const int n_passes = rop->passes();
  // The waveform records every event at its own cycle (waveform.h), so a
  // --vcd run stays decoupled like any other.
  const bool decoupled = !opt.lockstep;
  CycleStats& s = run.stats;
  s.hw = hw;
  s.hw.numerics = method.numerics;  // what ran: the method's (the CLI resolves flags and design into both)
  s.hw.blend.formats = target_formats(method);
  s.decoupled = decoupled;
  if (run_uses_transmittance(method.method, rop->setup().prepass)) s.listed |= 1u << int(Buffer::kTransmittance);
  if (run_uses_accum(method.method, rop->setup().prepass)) s.listed |= 1u << int(Buffer::kAccum);
  if (method.method == Method::kSlab) s.listed |= 1u << int(Buffer::kLayers);
  uint64_t progress_base = 0;
  // The waveform of every pass, one after the other (--vcd), opened before
  // the run so that a path that cannot be written fails at once.
  std::unique_ptr<OutputFile> vcd;
  std::unique_ptr<Waveform> wave;
  std::unique_ptr<OutputFile> gtkw;
  if (!opt.vcd_path.empty()) {
    vcd = std::make_unique<OutputFile>(opt.vcd_path);
    if (!opt.gtkw_path.empty()) gtkw = std::make_unique<OutputFile>(opt.gtkw_path);
    wave = std::make_unique<Waveform>(opt.vcd_first, opt.vcd_last);
  }
  if (opt.stats_interval > 0) run.intervals = std::make_unique<IntervalLog>(opt.stats_interval);
  // The DRAM bytes by draw and the per-tile figures (attribution.h): one
  // ledger for every pass.
  std::unique_ptr<Attribution> attr;
  if (opt.breakdown.any()) {
    run.breakdown = std::make_unique<RunBreakdown>(run.header, opt.breakdown.per_draw, opt.breakdown.per_pixel);
    const uint32_t tp = hw.distributor.tile_pixels;
    run.tiles_x = ceil_div(run.header.width, tp);
    run.tiles_y = ceil_div(run.header.height, tp);
    attr =
        std::make_unique<Attribution>(opt.breakdown.per_draw, opt.breakdown.per_pixel ? run.tiles_x * run.tiles_y : 0);
  }
  // A pass's retirements by (cycle, input order) and draw: the cycles from
  // one retirement to the next are the later one's draw's. Sorted at the end
  // of the pass: decoupled units may retire out of cycle order.
  struct Retired {
    uint64_t cycle, seq;
    uint32_t draw, tile;
  };
  std::vector<Retired> retired;
  for_each_pass(*rop, input, open_input, [&](int pass, int) {
    FreshSimContext sim;
    const char* top_name = n_passes > 1 ? to_string(rop->pass()) : "top";
    auto top = std::make_unique<RopPipeline>(top_name, std::move(input), *rop, in_dram, hw);
    if (opt.progress)
      top->source().on_progress = [&opt, progress_base, pass, n_passes](uint64_t n, double consumed) {
        opt.progress(progress_base + n, pass_progress(pass, n_passes, consumed));
      };
    top->retirement().hook = opt.retire_hook;
    if (RunBreakdown* b = run.breakdown.get()) {
      top->source().set_counting(true);
      top->retirement().hook = [b, &retired, user = opt.retire_hook](const FragToken& t, uint64_t cycle) {
        b->add(t.fragment, t.counts);
        retired.push_back(Retired{cycle, t.seq, t.fragment.draw_id, t.tile});
        if (user) user(t, cycle);
      };
    }
    if (IntervalLog* log = run.intervals.get()) {
      log->set_base(s.total_cycles);  // this pass follows the previous ones
      top->log_to(log);
      // The samples written (blended) since the last retirement are charged
      // to this one: every fragment's write comes before its retirement, so
      // the rows add up to the counters.
      top->retirement().hook =
          [log, r = rop.get(), user = top->retirement().hook, written = rop->write().counters().samples_written,
           blended = rop->blend().counters().samples_blended](const FragToken& t, uint64_t cycle) mutable {
            IntervalRow& row = log->row(cycle);
            ++row.fragments_retired;
            const uint64_t w = r->write().counters().samples_written, b = r->blend().counters().samples_blended;
            row.samples_written += w - written;
            row.samples_blended += b - blended;
            written = w;
            blended = b;
            if (user) user(t, cycle);
          };
    }
    top->set_decoupled(decoupled);
    top->compress_with(comp.get());
    top->attribute_to(attr.get());
    if (wave) {
      wave->set_base(s.total_cycles);  // this pass follows the previous ones
      top->trace_to(*wave, n_passes > 1 ? std::string(to_string(rop->pass())) + "." : "");
    }
    const auto t1 = std::chrono::steady_clock::now();
    top->run();  // on an error, vcd's destructor discards the file
    run.sim_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
    progress_base += top->source().produced();
    if (RunBreakdown* b = run.breakdown.get()) {
      std::sort(retired.begin(), retired.end(), [](const Retired& a, const Retired& c) {
        return a.cycle != c.cycle ? a.cycle < c.cycle : a.seq < c.seq;
      });
      uint64_t prev = 0;
      for (const Retired& r : retired) {
        b->add_cycles(r.draw, r.cycle - prev);
        attr->retire_cycles(r.tile, r.cycle - prev);
        prev = r.cycle;
      }
      retired.clear();
    }

    s.period_ps = top->clock().period_ps();
    s.total_cycles += top->total_cycles();
    s.pipeline_cycles += top->pipeline_cycles();
    const std::string prefix = n_passes > 1 ? std::string(to_string(rop->pass())) + "." : "";
    for (const auto& u : top->units()) {
      s.units.push_back(UnitReport{u.unit->name(), u.kind, u.rop, u.unit->stats(), u.unit->extras()});
      s.unit_runs += u.unit->stats().activations;
    }
    s.activations += top->activations();
    for (auto* f : top->fifos()) {
      s.fifos.push_back(f->stats(top->total_cycles()));
      s.fifos.back().name = prefix + s.fifos.back().name;
    }
    PassStats ps;
    ps.name = to_string(rop->pass());
    ps.total_cycles = top->total_cycles();
    ps.pipeline_cycles = top->pipeline_cycles();
    for (size_t r = 0; r < top->caches().size(); ++r) {
      const CacheStats c = top->caches()[r]->stats();
      if (s.caches.size() <= r) s.caches.emplace_back();
      s.caches[r] += c;
      ps.cache += c;
    }
    ps.dram = top->dram().stats();
    add_dram(s.dram, ps.dram);
    s.dram.last_completion = s.total_cycles;
    if (n_passes > 1) s.passes.push_back(ps);
    if (pass == 0 && n_passes == 1) s.dram = ps.dram;  // a single pass: its figures exactly
    s.tokens_allocated = std::max(s.tokens_allocated, top->tokens().allocated());
    top.reset();
  });
  if (wave) {
    const uint64_t end = s.total_cycles, shown = wave->last_shown(end);
    char comment[448];
    const int n = std::snprintf(comment, sizeof comment,
                                "ropsim cycle model. One clock cycle is ten time units of 100 ps, 1 ns (read "
                                "GTKWave's ns as cycles); clk rises at each cycle's start, where every signal "
                                "changes, and falls at its middle. The clock period is %llu ps at %g GHz. ",
                                (unsigned long long)s.period_ps, hw.clock.frequency_ghz);
    if (end > 0 && shown >= wave->first())
      std::snprintf(comment + n, sizeof comment - size_t(n), "Cycles %llu..%llu of a run of %llu.",
                    (unsigned long long)wave->first(), (unsigned long long)shown, (unsigned long long)end);
    else
      std::snprintf(comment + n, sizeof comment - size_t(n),
                    "The run ended (%llu cycles) before the window's first cycle %llu: no values.",
                    (unsigned long long)end, (unsigned long long)wave->first());
    wave->write_vcd("top", comment, end, [&vcd](std::string_view t) { vcd->write(t); });
    vcd->commit();
    if (gtkw) {  // the save file names the VCD by its absolute path: it opens from any folder
      gtkw->write(wave->write_gtkw(std::filesystem::absolute(opt.vcd_path).lexically_normal().string(), "top", end));
      gtkw->commit();
    }
  }
  if (run.intervals) run.intervals->finish(s.total_cycles);
  if (attr) {
    for (const auto& [draw, d] : attr->dram_by_draw()) run.breakdown->add_dram(draw, d.read, d.written);
    if (attr->tiles()) run.tiles = std::move(attr);
  }
  if (comp) {
    s.compression_on = true;
    s.compression = comp->stats();
  }
  s.frame_time_us = double(s.total_cycles) / (hw.clock.frequency_ghz * 1e3);
  run.counters = rop->counters();
  run.kind_fragments = rop->depth().kind_fragments();
  const double cyc = double(std::max<uint64_t>(1, s.total_cycles));
  s.fragments_per_clock = double(run.counters.fragments) / cyc;
  s.samples_per_clock = double(run.counters.samples_tested) / cyc;
  s.dram_peak_gbps = double(hw.dram.channels) * hw.dram.bytes_per_clock * hw.clock.frequency_ghz;
  const uint64_t bytes = s.dram.total_bytes_read() + s.dram.total_bytes_written();
  s.dram_achieved_gbps = s.frame_time_us > 0 ? double(bytes) / (s.frame_time_us * 1e3) : 0.0;
  s.dram_utilization = double(s.dram.max_channel_busy) / cyc;
  s.bottleneck = classify_bottleneck(s);
  s.memory_bound = s.bottleneck.kind == Bottleneck::Kind::kBandwidth;

  run.image = rop->resolve();
  run.state_bytes = rop->store().state_bytes();
  run.state = std::make_unique<SampleStore>(std::move(rop->store()));
  run.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return run;
}

}  // namespace ropsim

// libsystemc.so calls sc_main from its own main(); ropsim has its own main()
// and starts SystemC through run_cycle, so this is never called.
int sc_main(int, char**) { return 1; }
