// Bit-level functions shared by the golden model and the SystemC units.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <set>
#include <sstream>
#include <vector>

#include "rtl_models/algo/alpha_ref.h"
#include "rtl_models/algo/bits.h"
#include "rtl_models/algo/blend.h"
#include "rtl_models/algo/depth.h"
#include "rtl_models/algo/half.h"
#include "rtl_models/algo/hilbert.h"
#include "rtl_models/algo/method_kernels.h"
#include "rtl_models/algo/opacity.h"
#include "rtl_models/algo/random_hash.h"
#include "rtl_models/algo/slab.h"
#include "rtl_models/algo/sort_order.h"
#include "rtl_models/algo/tracker.h"
#include "tests/compare_util.h"

using namespace ropsim;

// ------------------------------------------------------------ bits.h

// Oracles: the plain loops the helpers replaced, in 64-bit arithmetic.
namespace {
int naive_log2_floor(uint64_t x) {
  int k = 0;
  while (k < 63 && (uint64_t{2} << k) <= x) ++k;
  return k;
}
int naive_log2_ceil(uint64_t x) {
  int k = 0;
  while (k < 64 && (uint64_t{1} << k) < x) ++k;
  return k;
}
template <class T>
void expect_bits_agree(T x) {
  const uint64_t v = x;
  EXPECT_EQ(is_pow2(x), v != 0 && naive_log2_floor(v) == naive_log2_ceil(v)) << v;
  EXPECT_EQ(log2_floor(x), naive_log2_floor(v)) << v;
  EXPECT_EQ(log2_ceil(x), naive_log2_ceil(v)) << v;
  if (naive_log2_ceil(v) < int(8 * sizeof(T))) {
    const uint64_t p = next_pow2(x);
    EXPECT_EQ(p, uint64_t{1} << naive_log2_ceil(v)) << v;
    EXPECT_TRUE(is_pow2(p) && p >= v && (p == 1 || p / 2 < v)) << v;
  }
}
}  // namespace

TEST(Bits, ExhaustiveOver16Bits) {
  for (uint32_t x = 0; x <= 0xFFFFu; ++x) {
    expect_bits_agree(uint16_t(x));
    expect_bits_agree(x);
    if (x <= 0xFF) expect_bits_agree(uint8_t(x));
    if (::testing::Test::HasFailure()) return;  // one bad value, not 65536 reports
  }
}

TEST(Bits, EdgesOf32And64Bits) {
  for (int k = 0; k < 64; ++k) {
    const uint64_t p = uint64_t{1} << k;
    for (uint64_t x : {p - 1, p, p + 1, p | (p >> 1), ~uint64_t{0} >> (63 - k)}) {
      expect_bits_agree(x);
      if (x <= UINT32_MAX) expect_bits_agree(uint32_t(x));
    }
    EXPECT_TRUE(is_pow2(p));
    EXPECT_EQ(log2_floor(p), k);
    EXPECT_EQ(log2_ceil(p), k);
    EXPECT_EQ(log2_ceil(p + 1), k + 1);
    EXPECT_EQ(next_pow2(p), p);
  }
  EXPECT_EQ(log2_floor(UINT64_MAX), 63);
  EXPECT_EQ(log2_ceil(UINT64_MAX), 64);
  EXPECT_EQ(log2_floor(UINT32_MAX), 31);
  EXPECT_EQ(log2_ceil(UINT32_MAX), 32);
  EXPECT_EQ(next_pow2(uint32_t{1} << 31), uint32_t{1} << 31);
  EXPECT_EQ(next_pow2(size_t{(1u << 20) + 1}), size_t{1} << 21);
  EXPECT_FALSE(is_pow2(UINT64_MAX));
  EXPECT_FALSE(is_pow2(uint64_t{0}));
  // Usable in constant expressions.
  static_assert(is_pow2(64u) && !is_pow2(0u) && !is_pow2(96u));
  static_assert(log2_floor(1u) == 0 && log2_floor(9u) == 3 && log2_ceil(9u) == 4 && log2_ceil(0u) == 0);
  static_assert(next_pow2(0u) == 1u && next_pow2(17u) == 32u && ceil_div(17u, 8u) == 3u);
  static_assert(low_mask(0) == 0 && low_mask(3) == 7 && low_mask(64) == ~uint64_t{0});
  static_assert(reverse_low_bits(1, 3) == 4 && reverse_low_bits(6, 3) == 3 && reverse_low_bits(5, 0) == 0);
}

TEST(Bits, CeilDiv) {
  for (uint32_t a = 0; a <= 0xFF; ++a)
    for (uint32_t b = 1; b <= 0xFF; ++b) {
      ASSERT_EQ(ceil_div(uint8_t(a), uint8_t(b)), (a + b - 1) / b) << a << " / " << b;
      ASSERT_EQ(ceil_div(a, b), (a + b - 1) / b) << a << " / " << b;
    }
  // No overflow at the top of the range, where (a + b - 1) / b wraps.
  EXPECT_EQ(ceil_div(UINT64_MAX, uint64_t{1}), UINT64_MAX);
  EXPECT_EQ(ceil_div(UINT64_MAX, uint64_t{2}), uint64_t{1} << 63);
  EXPECT_EQ(ceil_div(UINT64_MAX, UINT64_MAX), 1u);
  EXPECT_EQ(ceil_div(UINT32_MAX - 1, UINT32_MAX), 1u);
  EXPECT_EQ(ceil_div(uint32_t{0}, UINT32_MAX), 0u);
}

TEST(Bits, LowMaskAndBitReversal) {
  for (int b = 0; b <= 64; ++b) {
    const uint64_t m = low_mask(b);
    EXPECT_EQ(__builtin_popcountll(m), b);
    EXPECT_TRUE(m == 0 || (m & (m + 1)) == 0) << "low bits only: " << b;
  }
  EXPECT_EQ(low_mask(65), ~uint64_t{0});
  for (int m = 0; m <= 32; ++m)
    for (uint32_t x : {0u, 1u, 2u, 3u, 5u, 0x12345678u, 0xFFFFFFFFu}) {
      uint32_t want = 0;  // the bit loop the helper replaced
      for (int b = 0; b < m; ++b) want |= ((x >> b) & 1u) << (m - 1 - b);
      EXPECT_EQ(reverse_low_bits(x, m), want) << "x " << x << " m " << m;
    }
}

TEST(AlphaRef, ReproducesThePublishedValues) {
  // (sampleId 0, spp 1): (pixel, surface) -> CalcAlphaRef bits.
  struct Case {
    uint64_t pixel;
    uint32_t surface;
    uint32_t expect;
  };
  const Case cases[] = {
      {0, 0, 0x00000000u}, {1, 0, 0x80000000u}, {0, 1, 0x3707B665u}, {5, 7, 0xD1FDFF63u}, {12345, 678, 0x2ED32D8Eu}};
  for (const auto& c : cases)
    EXPECT_EQ(calc_alpha_ref(0, c.pixel, c.surface, 1), c.expect)
        << std::hex << "pixel " << c.pixel << " surface " << c.surface;
}

TEST(AlphaRef, ReverseBits) {
  EXPECT_EQ(reverse_bits32(1u), 0x80000000u);
  EXPECT_EQ(reverse_bits32(0x80000000u), 1u);
  EXPECT_EQ(reverse_bits32(0x12345678u), 0x1E6A2C48u);
  for (uint32_t x : {0u, 7u, 0xDEADBEEFu, 0xFFFFFFFFu}) EXPECT_EQ(reverse_bits32(reverse_bits32(x)), x);
}

// Every aligned power-of-two span of one pixel's sequence is stratified: the
// top log2(N) bits of the N references are a permutation (LK §3), for any
// pixel and surface id, including surface-id and index wrap.
TEST(AlphaRef, AlignedSpansAreStratified) {
  const uint64_t pixels[] = {0, 1, 2, 3, 1000, 123456, (1ull << 24) - 1, (1ull << 26) - 1, 1ull << 30};
  const uint32_t surfaces[] = {0, 1, 2, 77, 0x7FFFFFFFu, 0xFFFFFFFFu};
  for (uint32_t spp = 1; spp <= 64; spp *= 2)
    for (uint64_t p : pixels)
      for (uint32_t sid : surfaces) {
        const int L = log2_floor(spp);
        std::set<uint32_t> strata;
        for (uint32_t s = 0; s < spp; ++s) strata.insert(L ? calc_alpha_ref(s, p, sid, spp) >> (32 - L) : 0);
        EXPECT_EQ(strata.size(), spp) << "spp " << spp << " pixel " << p << " surface " << sid;
      }
}

TEST(AlphaRef, IndexWrapsModulo2To32) {
  // pixelId * spp beyond 32 bits (a 16384^2 screen at 64 spp) wraps like the
  // paper's 32-bit unsigned arithmetic.
  const uint64_t p = (1ull << 28) + 5;
  EXPECT_EQ(alpha_ref_index(3, p, 64), uint32_t((3 + p * 64) & 0xFFFFFFFFu));
  EXPECT_EQ(calc_alpha_ref(3, p, 9, 64), calc_alpha_ref(3, 5, 9, 64));
}

TEST(AlphaRef, NarrowHashStaysInRangeAndStratified) {
  for (int h : {8, 12, 16, 24}) {
    std::set<uint32_t> strata;
    for (uint32_t s = 0; s < 16; ++s) {
      uint32_t r = calc_alpha_ref(s, 4321, 5, 16, h);
      EXPECT_LT(r, 1u << h) << "hash_bits " << h;
      strata.insert(r >> (h - 4));
    }
    EXPECT_EQ(strata.size(), 16u) << "hash_bits " << h;
  }
  // The 32-bit path through the general function equals the paper's.
  EXPECT_EQ(calc_alpha_ref_index(alpha_ref_index(0, 12345, 1), 678, 32), 0x2ED32D8Eu);
}

// The batch form equals the single calls, across the 2^32 index wrap and for
// every hash width.
TEST(AlphaRef, BatchEqualsSingleCalls) {
  uint32_t out[64];
  for (int bits : {8, 12, 16, 24, 31, 32})
    for (uint32_t first : {0u, 5u, 0xFFFFFFF0u})
      for (uint64_t pixel : {uint64_t{0}, uint64_t{12345}, (uint64_t{1} << 30) - 1})
        for (uint32_t spp : {1u, 16u, 64u}) {
          calc_alpha_refs(first, 64, pixel, 678, spp, bits, out);
          for (int j = 0; j < 64; ++j)
            ASSERT_EQ(out[j], calc_alpha_ref(first + uint32_t(j), pixel, 678, spp, bits))
                << "bits " << bits << " first " << first << " pixel " << pixel << " spp " << spp << " j " << j;
        }
}

TEST(Hilbert, MatchesTheCanonicalFourByFour) {
  const uint64_t rows[4][4] = {{0, 1, 14, 15}, {3, 2, 13, 12}, {4, 7, 8, 11}, {5, 6, 9, 10}};
  for (uint32_t y = 0; y < 4; ++y)
    for (uint32_t x = 0; x < 4; ++x) EXPECT_EQ(hilbert_xy2d(4, x, y), rows[y][x]) << "x " << x << " y " << y;
}

// The state-machine walk equals the textbook quadrant-rotation loop
// (Wikipedia's xy2d), exhaustively up to 256 x 256 and on a sample of a
// 32768 x 32768 grid.
TEST(Hilbert, StateMachineEqualsTheRotationLoop) {
  auto reference = [](uint32_t n, uint32_t x, uint32_t y) {
    uint64_t d = 0;
    for (uint32_t s = n >> 1; s > 0; s >>= 1) {
      const uint32_t rx = (x & s) ? 1u : 0u, ry = (y & s) ? 1u : 0u;
      d += uint64_t{s} * s * ((3u * rx) ^ ry);
      if (ry == 0) {
        if (rx == 1) {
          x = s - 1 - (x & (s - 1));
          y = s - 1 - (y & (s - 1));
        }
        std::swap(x, y);
      }
    }
    return d;
  };
  for (uint32_t n = 1; n <= 256; n <<= 1)
    for (uint32_t y = 0; y < n; ++y)
      for (uint32_t x = 0; x < n; ++x)
        ASSERT_EQ(hilbert_xy2d(n, x, y), reference(n, x, y)) << n << " " << x << " " << y;
  std::mt19937 rng(5);
  for (int i = 0; i < 100000; ++i) {
    const uint32_t x = rng() % 32768, y = rng() % 32768;
    ASSERT_EQ(hilbert_xy2d(32768, x, y), reference(32768, x, y)) << x << " " << y;
  }
}

TEST(Hilbert, IsABijectionWithUnitSteps) {
  for (uint32_t n : {1u, 2u, 8u, 64u}) {
    std::vector<std::pair<uint32_t, uint32_t>> at(size_t(n) * n, {~0u, ~0u});
    for (uint32_t y = 0; y < n; ++y)
      for (uint32_t x = 0; x < n; ++x) {
        uint64_t d = hilbert_xy2d(n, x, y);
        ASSERT_LT(d, uint64_t(n) * n);
        ASSERT_EQ(at[d].first, ~0u) << "index " << d << " visited twice, n " << n;
        at[d] = {x, y};
      }
    for (size_t d = 1; d < at.size(); ++d) {
      int dx = std::abs(int(at[d].first) - int(at[d - 1].first)),
          dy = std::abs(int(at[d].second) - int(at[d - 1].second));
      EXPECT_EQ(dx + dy, 1) << "consecutive indices " << d - 1 << "," << d << " are not neighbours (n " << n << ")";
    }
  }
  EXPECT_EQ(hilbert_side(1920, 1080), 2048u);
  EXPECT_EQ(hilbert_side(4, 3), 4u);
  EXPECT_EQ(hilbert_side(1, 1), 1u);
  EXPECT_EQ(hilbert_xy2d(32768, 32767, 0), (1ull << 30) - 1);  // corner of the largest screen
}

TEST(Opacity, ExtremesAndExactProbability) {
  for (int b : {1, 8, 16, 24, 32}) {
    const uint64_t one = alpha_to_fixed(1.0f, b), zero = alpha_to_fixed(0.0f, b);
    EXPECT_EQ(one, uint64_t{1} << b);
    EXPECT_EQ(zero, 0u);
    for (uint32_t ref : {0u, 1u, 0x80000000u, 0xFFFFFFFFu}) {
      EXPECT_TRUE(opacity_passes(one, b, ref, 32)) << "alpha 1 must always write (bits " << b << ")";
      EXPECT_FALSE(opacity_passes(zero, b, ref, 32)) << "alpha 0 must never write (bits " << b << ")";
    }
  }
  // alpha = 2^-k is exact; alpha just below 1 still fails for the largest refs.
  EXPECT_EQ(alpha_to_fixed(0x1p-9f, 32), 1ull << 23);
  const uint64_t near_one = alpha_to_fixed(1.0f - 0x1p-24f, 32);
  EXPECT_EQ(near_one, (1ull << 32) - (1ull << 8));
  EXPECT_FALSE(opacity_passes(near_one, 32, 0xFFFFFFFFu, 32));
  EXPECT_TRUE(opacity_passes(near_one, 32, 0xFFFFFEFFu, 32));
  // alpha = 1e-6 keeps a non-zero probability of round(1e-6 * 2^32) / 2^32.
  EXPECT_EQ(alpha_to_fixed(1e-6f, 32), uint64_t(std::nearbyint(double(1e-6f) * 4294967296.0)));
  EXPECT_TRUE(opacity_passes(alpha_to_fixed(1e-6f, 32), 32, 0, 32));
  // P(pass) = A / 2^alpha_bits exactly when hash_bits >= alpha_bits: count over all refs of a 12-bit hash.
  const uint64_t a8 = alpha_to_fixed(0.3f, 8);
  int passes = 0;
  for (uint32_t r = 0; r < 4096; ++r) passes += opacity_passes(a8, 8, r, 12);
  EXPECT_EQ(uint64_t(passes), a8 * 16);
}

TEST(Tracker, FollowsFigure7) {
  TrackerState t;
  TrackResult r = track_surface(t, 0x00FF, 32);
  EXPECT_FALSE(r.new_surface);
  EXPECT_EQ(r.n, 0u);
  track_commit(t, 0x00FF);
  r = track_surface(t, 0xFF00, 32);  // disjoint: same surface continues at n = 8
  EXPECT_FALSE(r.new_surface);
  EXPECT_EQ(r.n, 8u);
  EXPECT_EQ(r.surface_id, 0u);
  track_commit(t, 0xFF00);
  r = track_surface(t, 0x0001, 32);  // conflict: new surface, mask cleared
  EXPECT_TRUE(r.new_surface);
  EXPECT_EQ(r.n, 0u);
  EXPECT_EQ(r.surface_id, 1u);
  track_commit(t, 0x0001);
  EXPECT_EQ(t.covered, 0x0001u);
}

TEST(Tracker, SurfaceIdWraps) {
  for (int bits : {1, 4, 8, 32}) {
    TrackerState t{~0ull, uint32_t(low_mask(bits))};
    TrackResult r = track_surface(t, 1, bits);
    EXPECT_TRUE(r.new_surface);
    EXPECT_EQ(r.surface_id, 0u) << "surface id of " << bits << " bits must wrap to 0";
  }
}

TEST(SortOrder, ByStoredDepthThenSampleId) {
  const float stored[6] = {1.0f, 0.5f, 1.0f, 0.25f, 0.5f, 0.0f};
  uint64_t keys[6];
  for (int i = 0; i < 6; ++i) keys[i] = sort_key(stored[i], uint32_t(i));
  sort_keys(keys, 6);
  const uint32_t expect[6] = {5, 3, 1, 4, 0, 2};
  for (int i = 0; i < 6; ++i) EXPECT_EQ(sort_key_sample(keys[i]), expect[i]) << "position " << i;
  // Same permutation as std::sort on random keys.
  uint64_t a[64], b[64];
  uint32_t s = 12345;
  for (int i = 0; i < 64; ++i) {
    s = s * 1664525u + 1013904223u;
    a[i] = b[i] = sort_key(float(s >> 28) / 16.0f, uint32_t(i));
  }
  sort_keys(a, 64);
  std::sort(b, b + 64);
  EXPECT_EQ(ropsim_test::first_element_difference(a, b), "");
}

TEST(Depth, PlaneTiesAndCanonicalZero) {
  EXPECT_TRUE(depth_passes(0.5f, 0.5f)) << "equal depth passes (LESS_EQUAL)";
  EXPECT_FALSE(depth_passes(0.50001f, 0.5f));
  EXPECT_EQ(depth_bits(canonical_depth(-0.0f)), 0u);
  EXPECT_EQ(canonical_depth(-3.0f), 0.0f);
  EXPECT_EQ(canonical_depth(2.0f), 1.0f);
  EXPECT_EQ(sample_offset(128), 0.0f);
  EXPECT_EQ(sample_offset(0), -0.5f);
  EXPECT_EQ(plane_depth(0.5f, 0.25f, -0.125f, 0.25f, 0.5f), 0.5f + 0.0625f - 0.0625f);
  // Binary64 evaluation, one rounding to binary32 at the end: z0 + dzdx*ox
  // is kept exact here where a binary32 evaluation would round it.
  const float z0 = 0.5f, g = 1.0f + 0x1p-23f, o = 1.0f / 256.0f;
  EXPECT_EQ(plane_depth(z0, g, 0.0f, o, 0.0f), float(0.5 + double(g) / 256.0));
  EXPECT_EQ(plane_depth(0.25f, g, -g, o, o), 0.25f) << "the two terms cancel exactly in binary64";
}

TEST(Half, RoundTripAndRounding) {
  for (float f : {0.0f, 0.25f, 0.5f, 1.0f, 0.7626953125f, 65504.0f, 0x1p-14f, 0x1p-24f})
    EXPECT_EQ(half_to_float(float_to_half(f)), f) << f;
  EXPECT_EQ(float_to_half(1.0f + 0x1p-11f), float_to_half(1.0f)) << "ties round to even";
  EXPECT_EQ(float_to_half(1.0f + 0x1p-11f + 0x1p-20f), float_to_half(1.0f) + 1);
  EXPECT_EQ(float_to_half(70000.0f), 0x7C00);
  for (uint32_t h = 0; h < 0x7C00; ++h) ASSERT_EQ(float_to_half(half_to_float(uint16_t(h))), h) << h;
}

namespace {
/// binary32 -> binary16 round to nearest even, computed in binary64 from the
/// definition: the nearest multiple of the half's spacing at f's magnitude,
/// ties to an even mantissa. Finite f only.
uint16_t reference_half(float f) {
  const double a = std::fabs(double(f));
  const uint16_t sign = std::signbit(f) ? 0x8000 : 0;
  if (a >= 65520.0) return sign | 0x7C00;
  int e = a < 0x1p-14 ? -14 : std::ilogb(a);   // subnormals share the smallest exponent
  const double ulp = std::ldexp(1.0, e - 10);  // spacing of halves at this magnitude
  double q = a / ulp, n = std::floor(q);
  if (q - n > 0.5 || (q - n == 0.5 && std::fmod(n, 2.0) == 1.0)) n += 1;
  // n * ulp is the half; encode it.
  const double v = n * ulp;
  if (v == 0) return sign;
  if (v < 0x1p-14) return uint16_t(sign | uint16_t(v / 0x1p-24));
  const int ev = std::ilogb(v);
  const uint16_t mant = uint16_t(std::ldexp(v, 10 - ev) - 1024.0);
  return uint16_t(sign | uint16_t((ev + 15) << 10) | mant);
}
}  // namespace

// The conversions have no data-dependent branch (blend.h's hot loop); they
// must equal the definition: every binary16 round-trips, and binary32 values
// across the whole range (every 251st bit pattern, about 17 million, plus the
// rounding boundaries) round to the nearest half, ties to even.
TEST(Half, EqualsTheDefinitionAcrossTheRange) {
  for (uint32_t h = 0; h < 0x10000; ++h) {
    const float f = half_to_float(uint16_t(h));
    if ((h & 0x7C00) == 0x7C00) {
      EXPECT_TRUE((h & 0x3FF) ? std::isnan(f) : std::isinf(f)) << h;
      continue;
    }
    ASSERT_EQ(float_to_half(f), h) << h;
    ASSERT_EQ(double(f),
              (h & 0x8000 ? -1.0 : 1.0) * ((h & 0x7C00) ? std::ldexp(1024.0 + (h & 0x3FF), ((h >> 10) & 31) - 25)
                                                        : std::ldexp(double(h & 0x3FF), -24)))
        << h;
  }
  auto check = [](uint32_t bits) {
    float f;
    std::memcpy(&f, &bits, 4);
    if (!std::isfinite(f)) return;
    ASSERT_EQ(float_to_half(f), reference_half(f)) << std::hex << bits;
  };
  for (uint64_t b = 0; b <= 0xFFFFFFFFull; b += 251) check(uint32_t(b));
  for (uint32_t h = 0; h < 0x7C00; ++h) {  // just below, at and just above each midpoint
    const double mid = (double(half_to_float(uint16_t(h))) + double(half_to_float(uint16_t(h + 1)))) / 2;
    const float m = float(mid);
    uint32_t mb;
    std::memcpy(&mb, &m, 4);
    for (uint32_t d : {mb - 1, mb, mb + 1}) check(d);
  }
}

#if defined(__SSE2__)
// The four-lane conversions of the blend unit's SSE path equal the scalar
// ones bit for bit: every binary16 value, and binary32 values across the
// whole range (every 61st bit pattern, NaNs and infinities included, plus
// the binary16 rounding boundaries and the subnormal range's edges).
TEST(Half, FourLaneConversionsEqualTheScalarOnes) {
  for (uint32_t h = 0; h < 0x10000; h += 4) {
    alignas(16) float got[4];
    _mm_store_ps(got, half4_to_float4(_mm_setr_epi32(int(h), int(h + 1), int(h + 2), int(h + 3))));
    for (uint32_t k = 0; k < 4; ++k) {
      const float want = half_to_float(uint16_t(h + k));
      ASSERT_EQ(std::memcmp(&got[k], &want, 4), 0) << std::hex << h + k;
    }
  }
  auto check4 = [](uint32_t b0, uint32_t b1, uint32_t b2, uint32_t b3) {
    const uint32_t in[4] = {b0, b1, b2, b3};
    alignas(16) uint32_t got[4];
    _mm_store_si128(reinterpret_cast<__m128i*>(got),
                    float4_to_half4(_mm_castsi128_ps(_mm_setr_epi32(int(b0), int(b1), int(b2), int(b3)))));
    for (int k = 0; k < 4; ++k) {
      float f;
      std::memcpy(&f, &in[k], 4);
      ASSERT_EQ(got[k], float_to_half(f)) << std::hex << in[k];
    }
  };
  for (uint64_t b = 0; b + 3 * 61 <= 0xFFFFFFFFull; b += 4 * 61)
    check4(uint32_t(b), uint32_t(b + 61), uint32_t(b + 122), uint32_t(b + 183));
  for (uint32_t sign : {0u, 0x80000000u}) {
    for (uint32_t h = 0; h < 0x7C00; ++h) {  // around each binary16 and each midpoint
      const float lo = half_to_float(uint16_t(h)), m = float((double(lo) + double(half_to_float(uint16_t(h + 1)))) / 2);
      uint32_t lb, mb;
      std::memcpy(&lb, &lo, 4);
      std::memcpy(&mb, &m, 4);
      check4(sign | (lb - 1), sign | lb, sign | (mb - 1), sign | mb);
      check4(sign | (mb + 1), sign | (lb + 1), sign | lb, sign | lb);
    }
    for (uint32_t b : {0x33000000u, 0x38800000u, 0x477FF000u, 0x47800000u, 0x7F800000u, 0x7FC00000u})
      check4(sign | (b - 1), sign | b, sign | (b + 1), sign | 0x7F800001u);
  }
}

// The blend unit's specialised blends (four channels as SSE lanes; a
// binary16 transmittance four samples at a time) equal the one definition,
// blend_multiply / blend_add of blend.h, on every target byte: random
// stored values (finite, subnormal, zero, infinite) and random factors.
TEST(Blend, SpecialisedBlendsEqualTheDefinition) {
  std::mt19937 rng(11);
  auto value = [&rng]() {
    const uint32_t r = rng();
    switch (r % 8) {
      case 0:
        return 0.0f;
      case 1:
        return float(r >> 8) * 0x1p-40f;  // binary16 subnormals and below
      case 2:
        return std::numeric_limits<float>::infinity();
      default:
        return std::ldexp(float(r >> 8) / float(1 << 24), int(r % 24) - 12);
    }
  };
  auto fill = [&](TargetFormat f, std::vector<uint8_t>& buf, int n) {
    buf.resize(size_t(n) * sample_bytes(f));
    for (int i = 0; i < n; ++i)
      for (int c = 0; c < channels(f); ++c) target_store(f, buf.data() + size_t(i) * sample_bytes(f), c, value());
  };
  for (int trial = 0; trial < 4000; ++trial) {
    const int spp = 1 << (trial % 7);
    const uint64_t mask = (uint64_t(rng()) << 32 | rng()) & (spp == 64 ? ~0ull : (uint64_t{1} << spp) - 1);
    const float factor = trial % 5 ? float(rng() % 4096) / 4096.0f : value();
    float src[4] = {value(), value(), value(), value()};
    if (trial % 3 == 0) src[1] = -src[1];
    std::vector<uint8_t> a, b;
    // Multiply: R16F and R32F per pixel (the sample loop), RGBA per sample.
    for (TargetFormat f : {TargetFormat::kR16F, TargetFormat::kR32F}) {
      fill(f, a, spp);
      b = a;
      if (f == TargetFormat::kR16F)
        blend_multiply_samples<TargetFormat::kR16F>(a.data(), mask, spp, factor);
      else
        blend_multiply_samples<TargetFormat::kR32F>(a.data(), mask, spp, factor);
      for (uint64_t m = mask; m; m &= m - 1)
        blend_multiply(f, b.data() + size_t(__builtin_ctzll(m)) * sample_bytes(f), factor);
      ASSERT_EQ(a, b) << to_string(f) << " spp " << spp << " trial " << trial;
    }
    for (TargetFormat f : {TargetFormat::kRGBA16F, TargetFormat::kRGBA32F}) {
      fill(f, a, 1);
      b = a;
      if (f == TargetFormat::kRGBA16F) {
        blend_multiply_as<TargetFormat::kRGBA16F>(a.data(), factor);
        blend_add_as<TargetFormat::kRGBA16F>(a.data(), src);
      } else {
        blend_multiply_as<TargetFormat::kRGBA32F>(a.data(), factor);
        blend_add_as<TargetFormat::kRGBA32F>(a.data(), src);
      }
      blend_multiply(f, b.data(), factor);
      blend_add(f, b.data(), src);
      ASSERT_EQ(a, b) << to_string(f) << " trial " << trial;
    }
  }
}

// The depth stage's four-at-a-time depths and test equal for_each_sample_depth
// and depth_passes, plane and per-sample, on every sample: random planes
// (depths below 0, above 1 and exactly representable ties included) and
// stored depths equal to the fragment's at some samples.
TEST(Depth, FourAtATimeEqualsTheSampleLoop) {
  std::mt19937 rng(7);
  auto uni = [&rng](float lo, float hi) { return lo + (hi - lo) * float(rng() >> 8) / float(1 << 24); };
  for (int trial = 0; trial < 20000; ++trial) {
    const int spp = 4 << (trial % 5);
    float ox[64], oy[64], per[64], stored[64];
    for (int i = 0; i < spp; ++i) {
      ox[i] = sample_offset(uint8_t(rng()));
      oy[i] = sample_offset(uint8_t(rng()));
      per[i] = trial % 7 == 0 ? -0.0f : uni(-0.25f, 1.25f);
    }
    const bool plane = trial % 2 == 0;
    const float z0 = uni(-0.1f, 1.1f), dzdx = uni(-0.5f, 0.5f), dzdy = trial % 11 ? uni(-0.5f, 0.5f) : 0.0f;
    float want[64];
    for_each_sample_depth((spp == 64 ? ~0ull : (uint64_t{1} << spp) - 1), plane, z0, dzdx, dzdy, ox, oy, per,
                          [&](int i, float zi) { want[i] = zi; });
    for (int i = 0; i < spp; ++i) stored[i] = rng() % 3 == 0 ? want[i] : canonical_depth(uni(-0.1f, 1.1f));
    float got[64];
    const uint64_t pass = sample_depths_and_test(spp, plane, z0, dzdx, dzdy, ox, oy, per, stored, got);
    for (int i = 0; i < spp; ++i) {
      ASSERT_EQ(depth_bits(got[i]), depth_bits(want[i])) << "trial " << trial << " sample " << i;
      ASSERT_EQ(bool(pass >> i & 1), depth_passes(want[i], stored[i])) << "trial " << trial << " sample " << i;
    }
    if (spp < 64) {
      ASSERT_EQ(pass >> spp, 0u);
    }
  }
}
#endif

TEST(SortOrder, GroupedSortEqualsKeySort) {
  uint32_t s = 777;
  for (int trial = 0; trial < 2000; ++trial) {
    float stored[64];
    const int distinct = 1 + trial % 9;
    for (int i = 0; i < 64; ++i) {
      s = s * 1664525u + 1013904223u;
      stored[i] = float((s >> 20) % unsigned(distinct)) / 8.0f;
    }
    s = s * 1664525u + 1013904223u;
    const uint64_t mask = (uint64_t(s) << 32 | (s * 2654435761u)) & (trial % 3 ? ~0ull : 0xFFFFull);
    uint64_t keys[64];
    int m = 0;
    for (uint64_t b = mask; b; b &= b - 1)
      keys[m++] = sort_key(stored[__builtin_ctzll(b)], uint32_t(__builtin_ctzll(b)));
    sort_keys(keys, m);
    uint8_t order[64];
    ASSERT_EQ(sort_by_stored_depth(stored, mask, order), m);
    for (int k = 0; k < m; ++k) ASSERT_EQ(order[k], sort_key_sample(keys[k])) << "trial " << trial << " position " << k;
  }
}

#include "sim/driver/vectors.h"

// Every unit's vectors: a header row, then `count` rows with as many columns.
TEST(Vectors, EveryUnitWritesWellFormedCsv) {
  for (const std::string& unit : vector_units()) {
    const std::string csv = make_vectors(unit, 200, 3, Numerics{});
    std::vector<std::string> lines;
    size_t start = 0;
    for (size_t nl; (nl = csv.find('\n', start)) != std::string::npos; start = nl + 1)
      lines.push_back(csv.substr(start, nl - start));
    ASSERT_EQ(lines.size(), 201u) << unit;
    const auto cols = std::count(lines[0].begin(), lines[0].end(), ',');
    for (size_t i = 1; i < lines.size(); ++i)
      ASSERT_EQ(std::count(lines[i].begin(), lines[i].end(), ','), cols) << unit << " row " << i << ": " << lines[i];
    EXPECT_EQ(make_vectors(unit, 200, 3, Numerics{}), csv) << unit << ": same seed, same vectors";
  }
  EXPECT_THROW(make_vectors("bogus", 1, 1, Numerics{}), VectorError);
  // The tracker row for a conflict: covered 0x00ff, surviving 0x0180 -> new surface 4, n 0.
  const std::string t = make_vectors("tracker", 3, 1, Numerics{});
  EXPECT_NE(t.find("16,32,00000000000000ff,3,0000000000000180,1,0,4,0000000000000180"), std::string::npos) << t;
}

// The hex format is the CSV's rows as $readmemh words: a comment block naming
// the fields, then one word per vector, every word as wide as the layout says.
TEST(Vectors, HexWordsMatchTheCsvRows) {
  for (const std::string& unit : vector_units()) {
    VectorOptions hex;
    hex.format = "hex";
    const std::string h = make_vectors(unit, 50, 3, Numerics{}, hex);
    std::istringstream in(h);
    int words = 0, comments = 0;
    size_t width = 0;
    int bits = 0;
    for (std::string line; std::getline(in, line);) {
      if (line.rfind("//", 0) == 0) {
        ++comments;
        if (comments == 1) {
          ASSERT_EQ(std::sscanf(line.c_str(), "// ropsim vectors %*s one %d-bit word", &bits), 1) << line;
        }
        continue;
      }
      ASSERT_EQ(line.find_first_not_of("0123456789abcdef"), std::string::npos) << unit << ": " << line;
      if (width == 0) width = line.size();
      ASSERT_EQ(line.size(), width) << unit << ": every word has the same width";
      ++words;
    }
    EXPECT_EQ(words, 50) << unit;
    EXPECT_EQ(int(width) * 4, bits) << unit << ": the header's word width";
    EXPECT_GT(comments, 1) << unit << ": the field layout";
  }
  // The alpha-ref word of pixel 12345, surface 678 (CSV: ref 2ed32d8e, spp 1).
  VectorOptions hex;
  hex.format = "hex";
  const std::string h = make_vectors("alpha-ref", 5, 1, Numerics{}, hex);
  // sample 0, pixel 12345 = 0x3039, surface 678 = 0x2a6, spp 1, hash bits 32
  EXPECT_NE(h.find("00000000"
                   "0000000000003039"
                   "000002a6"
                   "01"
                   "20"),
            std::string::npos)
      << h;
  EXPECT_NE(h.find("2ed32d8e\n"), std::string::npos) << h;
  VectorOptions bad;
  bad.spp = 3;
  EXPECT_THROW(make_vectors("sorter", 1, 1, Numerics{}, bad), VectorError);
}

// hashed-a2c (Wyman & McGuire 2017, Eq. 9): for every power-of-two n, a
// fragment's n thresholds fall one in each stratum [s/n, (s+1)/n), the offset
// and the odd increment are in range, and over many fragments every offset and
// every odd increment occurs (they come from the hash, not a fixed pattern).
TEST(HashedA2c, ThresholdsFallOneInEachStratum) {
  for (uint32_t n = 1; n <= 64; n *= 2) {
    // increments[i] for i <= max(n - 1, 1): n = 1 has the increment 1.
    std::vector<int> offsets(n, 0), increments(std::max<uint32_t>(n, 2), 0);
    for (uint32_t k = 0; k < 4000; ++k) {
      const uint64_t key = fragment_key(1, k % 7, k, k % 13, k % 17);
      const HashedA2cPattern p = hashed_a2c_pattern(key, n);
      ASSERT_LT(p.offset, n);
      ASSERT_EQ(p.increment % 2, 1u) << "the increment is odd";
      ASSERT_LE(p.increment, n == 1 ? 1u : n - 1);
      ++offsets[p.offset];
      ++increments[p.increment];
      std::vector<int> in_stratum(n, 0);
      for (uint32_t i = 0; i < n; ++i) {
        const uint64_t t = hashed_a2c_threshold(p, n, i);  // threshold * n * 2^32
        ASSERT_EQ(t & 0xFFFFFFFFu, p.chi) << "n " << n << ": the jitter is the fragment's chi";
        ++in_stratum[size_t(t >> 32)];
      }
      for (uint32_t s = 0; s < n; ++s)
        ASSERT_EQ(in_stratum[s], 1) << "n " << n << " key " << key << ": stratum " << s << " holds " << in_stratum[s]
                                    << " thresholds";
    }
    for (uint32_t s = 0; s < n; ++s) EXPECT_GT(offsets[s], 0) << "n " << n << ": offset " << s << " never drawn";
    for (uint32_t s = 1; s < n; s += 2)
      EXPECT_GT(increments[s], 0) << "n " << n << ": increment " << s << " never drawn";
  }
}

// With one chi per fragment the kept count is floor(alpha n + 1 - chi): never
// more than one away from alpha n; alpha 0 keeps none, alpha 1 keeps all.
TEST(HashedA2c, MaskKeepsAlphaNRoundedEitherWay) {
  for (uint32_t n = 1; n <= 64; n *= 2)
    for (float alpha : {0.0f, 1e-6f, 0.25f, 0.5f, 0.61f, 1.0f - 1e-6f, 1.0f})
      for (uint32_t k = 0; k < 200; ++k) {
        const uint64_t key = fragment_key(3, 0, k, 1, 2);
        const uint64_t a = alpha_to_fixed(alpha, 32);
        const uint64_t mask = hashed_a2c_mask(a, 32, n, key);
        ASSERT_EQ(mask & ~low_mask(int(n)), 0u);
        const int kept = __builtin_popcountll(mask);
        const double an = double(alpha) * n;
        ASSERT_GE(kept, int(std::floor(an))) << "n " << n << " alpha " << alpha;
        ASSERT_LE(kept, int(std::ceil(an))) << "n " << n << " alpha " << alpha;
        const HashedA2cPattern p = hashed_a2c_pattern(key, n);
        for (uint32_t i = 0; i < n; ++i)  // kept exactly where alpha > threshold
          ASSERT_EQ((mask >> i) & 1, uint64_t(double(a) * n > double(hashed_a2c_threshold(p, n, i))));
      }
}

namespace {
/// Stochastic transparency with b samples, by brute force: each bit takes the
/// colour of the nearest fragment covering it (later wins ties), else clear.
void brute_force_st(const std::vector<float>& z, const std::vector<uint64_t>& masks,
                    const std::vector<std::array<float, 3>>& rgb, int bits, const float clear[3], double out[3]) {
  for (int c = 0; c < 3; ++c) out[c] = 0;
  for (int j = 0; j < bits; ++j) {
    int best = -1;
    for (size_t f = 0; f < z.size(); ++f)
      if ((masks[f] >> j) & 1)
        if (best < 0 || z[f] <= z[size_t(best)]) best = int(f);
    for (int c = 0; c < 3; ++c) out[c] += best < 0 ? clear[c] : rgb[size_t(best)][c];
  }
  for (int c = 0; c < 3; ++c) out[c] /= bits;
}
}  // namespace

// With k at least the number of fragments, SLAB is stochastic transparency
// with b samples: for the same masks, its front-to-back resolve equals the
// per-bit nearest-fragment estimate (to binary32 rounding of the resolve),
// whatever the draw order; fragments it refuses as occluded change nothing.
TEST(Slab, KLargeIsStochasticTransparencyWithBSamples) {
  const float clear[3] = {0.1f, 0.2f, 0.3f};
  for (int bits : {1, 4, 8, 32, 64})
    for (uint32_t trial = 0; trial < 300; ++trial) {
      const uint64_t key = fragment_key(9, trial, uint32_t(bits), 0, 0);
      const int n = 1 + int(fragment_random(key, 0) % 12);
      std::vector<float> z;
      std::vector<uint64_t> masks;
      std::vector<std::array<float, 3>> rgb;
      SlabPixel p;
      float layer_rgb[kMaxSlabLayers][3];
      for (int f = 0; f < n; ++f) {
        z.push_back(float(fragment_random(key, 10 + uint32_t(f)) % 1000) / 1000.0f);
        const uint64_t m =
            (uint64_t(fragment_random(key, 30 + uint32_t(f))) << 32 | fragment_random(key, 50 + uint32_t(f))) &
            low_mask(bits);
        masks.push_back(m);
        const std::array<float, 3> c = {float(f) / 16, 1.0f - float(f) / 16, 0.5f};  // exact in binary16
        rgb.push_back(c);
        const uint16_t c16[3] = {float_to_half(c[0]), float_to_half(c[1]), float_to_half(c[2])};
        if (m && !slab_occluded(p, z.back(), m)) slab_insert(p, kMaxSlabLayers, z.back(), m, c16);
      }
      for (int l = 0; l < p.count; ++l)
        for (int c = 0; c < 3; ++c) layer_rgb[l][c] = half_to_float(p.rgb[l][c]);
      float got[3];
      slab_resolve(p, bits, layer_rgb, clear, got);
      double want[3];
      brute_force_st(z, masks, rgb, bits, clear, want);
      for (int c = 0; c < 3; ++c)
        ASSERT_NEAR(got[c], want[c], 1e-6) << "b " << bits << " trial " << trial << " channel " << c;
      for (int l = 1; l < p.count; ++l) ASSERT_LE(p.depth[l - 1], p.depth[l]) << "layers are kept nearest first";
    }
}

// k = 1 with opaque input (every bit covered) is a z-buffer: the one layer is
// always the nearest fragment so far (the later one on a tie).
TEST(Slab, KOneWithOpaqueInputIsAZBuffer) {
  for (uint32_t trial = 0; trial < 200; ++trial) {
    SlabPixel p;
    float nearest = 2;
    uint16_t nearest_id = 0;
    for (uint32_t f = 0; f < 20; ++f) {
      const float z = float(fragment_random(fragment_key(5, trial, f, 0, 0), 0) % 16) / 16.0f;
      const uint16_t c[3] = {uint16_t(f), 0, 0};
      if (!slab_occluded(p, z, low_mask(32))) slab_insert(p, 1, z, low_mask(32), c);
      if (z <= nearest) {
        nearest = z;
        nearest_id = uint16_t(f);
      }
      ASSERT_EQ(p.count, 1);
      ASSERT_EQ(p.depth[0], nearest);
      ASSERT_EQ(p.rgb[0][0], nearest_id) << "trial " << trial << " after fragment " << f;
    }
  }
}

// Beyond k layers the furthest is the one dropped: whether the new fragment
// lands in front of the stored layers (the last stored layer falls off) or
// behind all of them (it is itself dropped).
TEST(Slab, TheFurthestLayerIsDropped) {
  const uint16_t c[3] = {0, 0, 0};
  SlabPixel p;
  // Disjoint masks: no layer occludes another, so only k limits the list.
  for (int i = 0; i < 3; ++i) EXPECT_EQ(slab_insert(p, 3, 0.2f + 0.2f * float(i), uint64_t{1} << i, c), i);
  ASSERT_EQ(p.count, 3);
  EXPECT_EQ(slab_insert(p, 3, 0.9f, uint64_t{1} << 3, c), 3) << "the furthest new fragment is dropped";
  EXPECT_EQ(p.count, 3);
  EXPECT_EQ(p.depth[2], 0.6f);
  EXPECT_EQ(slab_insert(p, 3, 0.3f, uint64_t{1} << 4, c), 1) << "inserted between 0.2 and 0.4";
  ASSERT_EQ(p.count, 3);
  EXPECT_EQ(p.depth[0], 0.2f);
  EXPECT_EQ(p.depth[1], 0.3f);
  EXPECT_EQ(p.depth[2], 0.4f) << "0.6, the furthest, was dropped";
  EXPECT_EQ(p.mask[2], uint64_t{1} << 1);
  EXPECT_EQ(slab_insert(p, 3, 0.1f, uint64_t{1} << 5, c), 0);
  EXPECT_EQ(p.depth[2], 0.3f) << "0.4, now the furthest, was dropped";
}

// The stratified mask: floor(alpha |C| + xi) bits (so within one of alpha |C|),
// all among the candidate bits, alpha 0 none and alpha 1 all of them.
TEST(Slab, MaskIsStratifiedAmongTheCandidateBits) {
  for (uint32_t t = 0; t < 2000; ++t) {
    const uint64_t key = fragment_key(2, t, 0, 1, 1);
    const uint64_t cand = (uint64_t(fragment_random(key, 100)) << 32 | fragment_random(key, 101)) | 1;
    const int nc = __builtin_popcountll(cand);
    for (float alpha : {0.0f, 0.3f, 0.5f, 1.0f}) {
      uint32_t hashes = 0;
      const uint64_t m = slab_mask(alpha_to_fixed(alpha, 32), 32, cand, key, &hashes);
      ASSERT_EQ(m & ~cand, 0u);
      const int r = __builtin_popcountll(m);
      ASSERT_GE(r, int(std::floor(double(alpha) * nc)));
      ASSERT_LE(r, int(std::ceil(double(alpha) * nc)));
      ASSERT_EQ(hashes, uint32_t(r) + 1);
    }
  }
  // Sample s owns bits [s b / spp, (s + 1) b / spp) when b >= spp.
  const auto own = slab_sample_bits(4, 32);
  EXPECT_EQ(own[0], 0xFFull);
  EXPECT_EQ(own[3], 0xFF000000ull);
  EXPECT_EQ(slab_sample_bits(16, 4)[4], 0x2ull) << "b < spp: bit j stands for sample j spp / b";
}
