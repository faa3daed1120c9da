// The six testbenches (docs/rtl.md "Testbenches"). Each drives its model with
// ropsim's vectors for the model's parameters, then with random inputs, one
// per clock with gaps, and compares every output bit against the C++ rule of
// rtl_models/algo that the golden model calls; then measures the pipeline
// latency and checks it against the SystemC unit's timing rule.
#pragma once
#include <algorithm>
#include <cstring>

#include "rtl_models/algo/alpha_ref.h"
#include "rtl_models/algo/depth.h"
#include "rtl_models/algo/hilbert.h"
#include "rtl_models/algo/opacity.h"
#include "rtl_models/algo/sort_order.h"
#include "rtl_models/algo/tracker.h"
#include "rtl_models/config/hw_config.h"
#include "rtl_models/sorter/sort_algorithm.h"
#include "rtl_models/units/unit_timing.h"
#include "tests/rtl/tb_common.h"

namespace rtl_tb {

inline float as_float(uint32_t b) {
  float f;
  std::memcpy(&f, &b, 4);
  return f;
}

/// A canonical depth (binary32 in [+0, 1]) with many ties: cleared 1.0,
/// quarters, or uniform in [0, 1).
inline uint32_t random_depth(Rng& r) {
  switch (r.below(4)) {
    case 0:
      return 0x3F800000u;
    case 1:
      return ropsim::depth_bits(float(r.below(4)) * 0.25f);
    default:
      return ropsim::depth_bits(float(r.u64() >> 40) * 0x1p-24f);
  }
}

/// A sample mask of `spp` bits: sparse, dense, full or uniform.
inline uint64_t random_mask(Rng& r, int spp) {
  uint64_t m = r.u64();
  switch (r.below(4)) {
    case 0:
      m &= r.u64();
      break;
    case 1:
      m |= r.u64();
      break;
    case 2:
      m = ~0ull;
      break;
    default:
      break;
  }
  return m & mask_of(spp);
}

// ------------------------------------------------------------- alpha-ref
template <class M>
Report tb_alpha_ref(const Params& p, const Options& o) {
  const int L = p["LANES"], S = p["STAGES"], H = p["HASH_BITS"], SPP = p["SPP"], SB = p["SID_BITS"],
            PB = p["PIXEL_BITS"];
  struct In {
    uint32_t first;
    uint64_t pixel;
    uint32_t sid;
    uint32_t want0;  // lane 0's expected value from the vector file (or the C++ rule)
  };
  Pipe<M> pipe;
  M& m = pipe.m();
  auto drive = [&](const In& in) {
    m.first = in.first;
    m.pixel_id = in.pixel;
    m.surface_id = in.sid;
  };
  auto check = [&](const In& in, uint64_t k) {
    uint32_t want[64] = {};
    ropsim::calc_alpha_refs(in.first, L, in.pixel, in.sid, uint32_t(SPP), H, want);
    expect_eq(get(m.ref_out, 0, H), in.want0, "lane 0 against the vector", k);
    for (int j = 0; j < L; ++j) expect_eq(get(m.ref_out, j * H, H), want[j], "ref of lane " + std::to_string(j), k);
  };
  Report rep;
  Rng rng(o.seed);
  // 1. ropsim's vectors (those whose pixel and surface ids fit the ports).
  const VectorFile v = ropsim_vectors(
      o, "alpha-ref",
      "--spp " + std::to_string(SPP) + " --hash-bits " + std::to_string(H) + " --surface-id-bits " + std::to_string(SB),
      "alpha_ref");
  std::vector<In> vin;
  for (size_t k = 0; k < v.words.size(); ++k) {
    const uint64_t pixel = v.get(k, "pixel_id");
    const uint64_t sid = v.get(k, "surface_id");
    // Pixel-id bits at and above HASH_BITS - log2(SPP) do not reach the hash:
    // a narrower port is exact when PIXEL_BITS covers the rest.
    const bool pixel_exact = PB + __builtin_ctz(unsigned(SPP)) >= H;
    if ((!pixel_exact && (pixel & ~mask_of(PB))) || (sid & ~mask_of(SB))) continue;
    const uint32_t first = uint32_t(v.get(k, "sample_id"));
    vin.push_back({first, pixel & mask_of(PB), uint32_t(sid), uint32_t(v.get(k, "ref"))});
    // The file's index column is the index formation of lane 0.
    expect_eq(v.get(k, "index"), ropsim::alpha_ref_index(first, pixel, uint32_t(SPP), H), "vector index", k);
  }
  if (vin.size() < v.words.size() / 2) throw Failure("fewer than half the vectors fit the ports");
  pipe.template stream<In>(
      vin.size(), rng, [&](uint64_t k) { return vin[k]; }, drive, check);
  rep.vectors = vin.size();
  // 2. Random inputs: indices near the 2^32 wrap, pixel ids up to the port width.
  pipe.template stream<In>(
      o.random, rng,
      [&](uint64_t) {
        In in;
        in.first = rng.below(4) ? uint32_t(rng.u64()) : uint32_t(-1 - int32_t(rng.below(64)));
        in.pixel = rng.bits(PB);
        in.sid = uint32_t(rng.below(2) ? rng.bits(SB) : rng.below(16) & mask_of(SB));
        in.want0 = ropsim::calc_alpha_ref(in.first, in.pixel, in.sid, uint32_t(SPP), H);
        return in;
      },
      drive, check);
  rep.random = o.random;
  // 3. Latency: a fragment of m hashes enters over ceil(m / LANES) clocks;
  // the SystemC AlphaRefGen's rule gives the cycles to its last reference.
  ropsim::HwConfig::AlphaRef cfg;
  cfg.lanes = uint32_t(L);
  cfg.pipeline_depth = uint32_t(S);
  for (uint32_t hashes : {1u, uint32_t(L), uint32_t(2 * L + 1)}) {
    const ropsim::UnitTiming t = ropsim::alpha_ref_timing(cfg, hashes);
    const uint32_t got = pipe.measure_burst([&](uint32_t c) { drive({c * uint32_t(L), 7, 3, 0}); }, t.interval);
    if (got != t.latency)
      throw Failure("latency of " + std::to_string(hashes) + " hashes: RTL " + std::to_string(got) +
                    " cycles, SystemC AlphaRefGen " + std::to_string(t.latency));
    rep.latency = got;
    rep.expected_latency = t.latency;
  }
  return rep;
}

// ---------------------------------------------------------- opacity test
template <class M>
Report tb_opacity(const Params& p, const Options& o) {
  const int L = p["LANES"], AB = p["ALPHA_BITS"], H = p["HASH_BITS"], S = p["STAGES"];
  struct In {
    uint64_t a;
    uint32_t ref[64];
    uint64_t mask;
    int want0;  // lane 0 from the vector file, -1 for a random input
  };
  Pipe<M> pipe;
  M& m = pipe.m();
  auto drive = [&](const In& in) {
    m.a_fixed = in.a;
    for (int j = 0; j < L; ++j) put(m.refs, j * H, H, in.ref[j]);
    m.mask = in.mask;
  };
  auto check = [&](const In& in, uint64_t k) {
    if (in.want0 >= 0) expect_eq(get(m.pass, 0, 1), uint64_t(in.want0), "lane 0 against the vector", k);
    uint64_t want = 0;
    for (int j = 0; j < L; ++j)
      if ((in.mask >> j & 1) && ropsim::opacity_passes(in.a, AB, in.ref[j], H)) want |= uint64_t{1} << j;
    expect_eq(get(m.pass, 0, L), want, "pass", k);
  };
  Rng rng(o.seed);
  const uint64_t a_max = uint64_t{1} << AB;
  auto near_ref = [&](uint64_t a) {  // a reference on or next to the threshold of a
    const uint64_t on = AB >= H ? a >> (AB - H) : a << (H - AB);
    return uint32_t((std::min<uint64_t>(on, mask_of(H)) + rng.below(3) - 1) & mask_of(H));
  };
  Report rep;
  const VectorFile v = ropsim_vectors(
      o, "opacity", "--alpha-bits " + std::to_string(AB) + " --hash-bits " + std::to_string(H), "opacity");
  pipe.template stream<In>(
      v.words.size(), rng,
      [&](uint64_t k) {
        In in;
        in.a = v.get(k, "a_fixed");
        in.ref[0] = uint32_t(v.get(k, "ref"));
        for (int j = 1; j < L; ++j) in.ref[j] = uint32_t(rng.bits(H));
        in.mask = mask_of(L);
        in.want0 = int(v.get(k, "pass"));
        return in;
      },
      drive, check);
  rep.vectors = v.words.size();
  pipe.template stream<In>(
      o.random, rng,
      [&](uint64_t) {
        In in;
        in.a = rng.below(8) == 0 ? (rng.below(2) ? 0 : a_max) : rng.u64() % (a_max + 1);
        for (int j = 0; j < L; ++j) in.ref[j] = rng.below(2) ? near_ref(in.a) : uint32_t(rng.bits(H));
        in.mask = random_mask(rng, L);
        in.want0 = -1;
        return in;
      },
      drive, check);
  rep.random = o.random;
  // The opacity test has no SystemC unit of its own (it is part of the
  // writeback unit's latency): its latency is its STAGES parameter.
  rep.latency = pipe.measure_latency([&] { drive(In{1, {0}, 1, -1}); });
  rep.expected_latency = uint32_t(S);
  if (rep.latency != rep.expected_latency)
    throw Failure("latency " + std::to_string(rep.latency) + " cycles, STAGES " + std::to_string(S));
  return rep;
}

// ------------------------------------------------------- tracker update
template <class M>
Report tb_tracker(const Params& p, const Options& o) {
  const int SPP = p["SPP"], SB = p["SID_BITS"], S = p["STAGES"];
  struct In {
    uint64_t covered, surviving;
    uint32_t sid;
  };
  Pipe<M> pipe;
  M& m = pipe.m();
  auto drive = [&](const In& in) {
    m.covered_in = in.covered;
    m.surface_id_in = in.sid;
    m.surviving = in.surviving;
  };
  auto check = [&](const In& in, uint64_t k) {
    ropsim::TrackerState t{in.covered, in.sid};
    const ropsim::TrackResult r = ropsim::track_surface(t, in.surviving, SB);
    ropsim::track_commit(t, in.surviving);
    expect_eq(m.new_surface, r.new_surface, "new_surface", k);
    expect_eq(m.n, r.n, "n", k);
    expect_eq(m.surface_id_out, t.surface_id, "surface_id_out", k);
    expect_eq(get(m.covered_out, 0, SPP), t.covered, "covered_out", k);
    if (r.surface_id != t.surface_id) throw Failure("C++ tracker: surface ids differ");
  };
  Rng rng(o.seed);
  Report rep;
  const VectorFile v = ropsim_vectors(
      o, "tracker", "--spp " + std::to_string(SPP) + " --surface-id-bits " + std::to_string(SB), "tracker");
  auto vec_in = [&](uint64_t k) {
    return In{v.get(k, "covered_in"), v.get(k, "surviving"), uint32_t(v.get(k, "surface_id_in"))};
  };
  pipe.template stream<In>(v.words.size(), rng, vec_in, drive, [&](const In& in, uint64_t k) {
    check(in, k);
    expect_eq(m.new_surface, v.get(k, "new_surface"), "new_surface against the vector", k);
    expect_eq(m.n, v.get(k, "n"), "n against the vector", k);
    expect_eq(m.surface_id_out, v.get(k, "surface_id_out"), "surface_id_out against the vector", k);
    expect_eq(get(m.covered_out, 0, SPP), v.get(k, "covered_out"), "covered_out against the vector", k);
  });
  rep.vectors = v.words.size();
  pipe.template stream<In>(
      o.random, rng,
      [&](uint64_t) {
        In in{random_mask(rng, SPP), random_mask(rng, SPP), uint32_t(rng.bits(SB))};
        if (rng.below(8) == 0) in.sid = uint32_t(mask_of(SB));  // the wrap
        if (rng.below(4) == 0) in.surviving &= ~in.covered;     // disjoint: same surface
        return in;
      },
      drive, check);
  rep.random = o.random;
  ropsim::HwConfig::Tracker cfg;
  cfg.latency_cycles = uint32_t(S);
  rep.expected_latency = ropsim::tracker_timing(cfg).latency;
  rep.latency = pipe.measure_latency([&] { drive(In{1, 1, 0}); });
  if (rep.latency != rep.expected_latency)
    throw Failure("latency " + std::to_string(rep.latency) + " cycles, SystemC CoverageTracker " +
                  std::to_string(rep.expected_latency));
  return rep;
}

// ------------------------------------------------------- depth compare
template <class M>
Report tb_depth_compare(const Params& p, const Options& o) {
  const int L = p["LANES"], S = p["STAGES"];
  struct In {
    uint64_t covered;
    uint32_t z[64], stored[64];
    int64_t want;  // pass mask from the vector file, -1 for a random input
  };
  Pipe<M> pipe;
  M& m = pipe.m();
  auto drive = [&](const In& in) {
    m.covered = in.covered;
    for (int j = 0; j < L; ++j) {
      put(m.z, 32 * j, 32, in.z[j]);
      put(m.stored, 32 * j, 32, in.stored[j]);
    }
  };
  auto check = [&](const In& in, uint64_t k) {
    uint64_t want = 0;
    for (int j = 0; j < L; ++j)
      if ((in.covered >> j & 1) && ropsim::depth_passes(as_float(in.z[j]), as_float(in.stored[j])))
        want |= uint64_t{1} << j;
    expect_eq(get(m.pass, 0, L), want, "pass", k);
    if (in.want >= 0) expect_eq(want, uint64_t(in.want), "pass against the vector", k);
  };
  Rng rng(o.seed);
  Report rep;
  // The vectors' sample depths come from the plane evaluation (plane_depth);
  // the module is the compare that follows it.
  const VectorFile v = ropsim_vectors(o, "depth-test", "--spp " + std::to_string(L), "depth_test");
  pipe.template stream<In>(
      v.words.size(), rng,
      [&](uint64_t k) {
        In in;
        in.covered = v.get(k, "coverage");
        for (int j = 0; j < L; ++j) {
          in.z[j] = uint32_t(v.get(k, "sample_depths", j));
          in.stored[j] = uint32_t(v.get(k, "stored_depths", j));
        }
        in.want = int64_t(v.get(k, "pass"));
        return in;
      },
      drive, check);
  rep.vectors = v.words.size();
  pipe.template stream<In>(
      o.random, rng,
      [&](uint64_t) {
        In in;
        in.covered = random_mask(rng, L);
        for (int j = 0; j < L; ++j) {
          in.stored[j] = random_depth(rng);
          const uint32_t r = rng.below(4);  // equal, one ulp either side, or any
          in.z[j] = r == 0   ? in.stored[j]
                    : r == 1 ? std::min(in.stored[j] + 1, 0x3F800000u)
                    : r == 2 ? (in.stored[j] ? in.stored[j] - 1 : 0)
                             : random_depth(rng);
        }
        in.want = -1;
        return in;
      },
      drive, check);
  rep.random = o.random;
  // The SystemC DepthTest sends a fragment on depth_test.latency_cycles after
  // its stored depths arrive: the module's STAGES.
  ropsim::HwConfig::DepthTest cfg;
  cfg.latency_cycles = uint32_t(S);
  rep.expected_latency = cfg.latency_cycles;
  rep.latency = pipe.measure_latency([&] { drive(In{1, {0}, {0}, -1}); });
  if (rep.latency != rep.expected_latency)
    throw Failure("latency " + std::to_string(rep.latency) + " cycles, depth_test.latency_cycles " +
                  std::to_string(rep.expected_latency));
  return rep;
}

// -------------------------------------------------------- Hilbert index
template <class M>
Report tb_hilbert(const Params& p, const Options& o) {
  const int K = p["ORDER"], S = p["STAGES"];
  struct In {
    uint32_t x, y;
    int64_t want;
  };
  Pipe<M> pipe;
  M& m = pipe.m();
  auto drive = [&](const In& in) {
    m.x = in.x;
    m.y = in.y;
  };
  auto check = [&](const In& in, uint64_t k) {
    const uint64_t want = ropsim::hilbert_xy2d(1u << K, in.x, in.y);
    expect_eq(get(m.d, 0, 2 * K), want, "d", k);
    if (in.want >= 0) expect_eq(want, uint64_t(in.want), "d against the vector", k);
  };
  Rng rng(o.seed);
  Report rep;
  const VectorFile v = ropsim_vectors(o, "hilbert", "--order " + std::to_string(K), "hilbert");
  pipe.template stream<In>(
      v.words.size(), rng,
      [&](uint64_t k) {
        return In{uint32_t(v.get(k, "x")), uint32_t(v.get(k, "y")), int64_t(v.get(k, "d"))};
      },
      drive, check);
  rep.vectors = v.words.size();
  pipe.template stream<In>(
      o.random, rng,
      [&](uint64_t) {
        return In{uint32_t(rng.bits(K)), uint32_t(rng.bits(K)), -1};
      },
      drive, check);
  rep.random = o.random;
  // No SystemC unit of its own (the pixel id is part of the alpha-reference
  // stage's input): the latency is the STAGES parameter.
  rep.expected_latency = uint32_t(S);
  rep.latency = pipe.measure_latency([&] { drive(In{1, 1, -1}); });
  if (rep.latency != rep.expected_latency)
    throw Failure("latency " + std::to_string(rep.latency) + " cycles, STAGES " + std::to_string(S));
  return rep;
}

// -------------------------------------------------------- bitonic sorter
template <class M>
Report tb_sorter(const Params& p, const Options& o) {
  const int N = p["N"];
  struct In {
    uint64_t surviving;
    uint32_t depth[64];
    int order[64];  // the vector file's order (-1 past the survivors), or order[0] = -2 for random input
  };
  Pipe<M> pipe;
  M& m = pipe.m();
  auto drive = [&](const In& in) {
    m.surviving = in.surviving;
    for (int i = 0; i < N; ++i) put(m.stored_depth, 32 * i, 32, in.depth[i]);
  };
  auto check = [&](const In& in, uint64_t k) {
    // Survivors: the golden model's sorter (sort_by_stored_depth).
    float d[64] = {};
    for (int i = 0; i < N; ++i) d[i] = as_float(in.depth[i]);
    uint8_t order[64];
    const int mcount = ropsim::sort_by_stored_depth(d, in.surviving, order);
    // Every position: the sort keys (sort_key) of all N samples, the
    // non-survivors' above the survivors', in sort_keys order.
    uint64_t keys[64];
    for (int i = 0; i < N; ++i)
      keys[i] = (uint64_t((in.surviving >> i & 1) ^ 1) << 38) | ropsim::sort_key(d[i], uint32_t(i));
    ropsim::sort_keys(keys, N);
    for (int pos = 0; pos < N; ++pos) {
      const uint64_t id = get(m.order_id, 6 * pos, 6), valid = get(m.order_valid, pos, 1);
      expect_eq(id, ropsim::sort_key_sample(keys[pos]), "order_id[" + std::to_string(pos) + "]", k);
      expect_eq(valid, pos < mcount, "order_valid[" + std::to_string(pos) + "]", k);
      if (pos < mcount) expect_eq(id, order[pos], "survivor " + std::to_string(pos) + " against the golden order", k);
      if (pos < mcount && in.order[0] != -2)
        expect_eq(id, uint64_t(in.order[pos]), "survivor " + std::to_string(pos) + " against the vector", k);
    }
  };
  Rng rng(o.seed);
  Report rep;
  const VectorFile v = ropsim_vectors(o, "sorter", "--spp " + std::to_string(N), "sorter");
  pipe.template stream<In>(
      v.words.size(), rng,
      [&](uint64_t k) {
        In in;
        in.surviving = v.get(k, "surviving");
        const int mc = __builtin_popcountll(in.surviving);
        for (int i = 0; i < N; ++i) {
          in.depth[i] = uint32_t(v.get(k, "stored_depths", i));
          in.order[i] = i < mc ? int(v.get(k, "order", i)) : -1;
        }
        return in;
      },
      drive, check);
  rep.vectors = v.words.size();
  pipe.template stream<In>(
      o.random, rng,
      [&](uint64_t) {
        In in;
        in.surviving = random_mask(rng, N);
        for (int i = 0; i < N; ++i) in.depth[i] = random_depth(rng);
        in.order[0] = -2;
        return in;
      },
      drive, check);
  rep.random = o.random;
  // The SystemC SampleSorter takes its timing from the bitonic SortAlgorithm.
  const auto algo = ropsim::make_sorter(ropsim::SorterKind::kBitonic, N);
  rep.expected_latency = algo->latency_cycles(N);
  rep.latency = pipe.measure_latency([&] { drive(In{1, {0}, {0}}); });
  if (rep.latency != rep.expected_latency)
    throw Failure("latency " + std::to_string(rep.latency) + " cycles, SystemC bitonic sorter " +
                  std::to_string(rep.expected_latency));
  if (algo->interval_cycles(N) != 1) throw Failure("the SystemC bitonic sorter is not fully pipelined");
  return rep;
}

}  // namespace rtl_tb
