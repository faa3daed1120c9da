// Integer bit helpers -- powers of two, base-2 logarithms, rounding-up
// division and low-bit masks -- defined once for the whole simulator (C++17
// has no <bit>). Everything is constexpr. The templates take unsigned
// integers only: a signed argument does not compile, so a caller converts
// explicitly where it knows the value is not negative.
#pragma once
#include <cstdint>
#include <type_traits>

namespace ropsim {

namespace bits_detail {
template <class T>
inline constexpr bool kUnsigned = std::is_unsigned_v<T> && !std::is_same_v<T, bool>;
}  // namespace bits_detail

/// True when x is 1, 2, 4, 8, ...; false for 0 and every other value.
template <class T>
constexpr bool is_pow2(T x) {
  static_assert(bits_detail::kUnsigned<T>, "is_pow2 takes an unsigned integer");
  return x != 0 && (x & (x - 1)) == 0;
}

/// floor(log2(x)): the index of the highest set bit (log2_floor(8) = 3,
/// log2_floor(9) = 3). For x = 0, which has no logarithm, 0.
template <class T>
constexpr int log2_floor(T x) {
  static_assert(bits_detail::kUnsigned<T>, "log2_floor takes an unsigned integer");
  return x == 0 ? 0 : 63 - __builtin_clzll(static_cast<unsigned long long>(x));
}

/// ceil(log2(x)): the smallest k with 2^k >= x (log2_ceil(8) = 3,
/// log2_ceil(9) = 4); 0 for x <= 1. Equals log2_floor(x) for a power of two,
/// so it is also the shift that divides by a power of two.
template <class T>
constexpr int log2_ceil(T x) {
  static_assert(bits_detail::kUnsigned<T>, "log2_ceil takes an unsigned integer");
  return x <= 1 ? 0 : log2_floor(static_cast<unsigned long long>(x - 1)) + 1;
}

/// The smallest power of two >= x (1 for x = 0 and 1). x must not exceed the
/// largest power of two of T (2^31 for uint32_t): the result would not fit.
template <class T>
constexpr T next_pow2(T x) {
  static_assert(bits_detail::kUnsigned<T>, "next_pow2 takes an unsigned integer");
  return static_cast<T>(static_cast<unsigned long long>(1) << log2_ceil(x));
}

/// ceil(a / b) for b > 0, without the overflow of (a + b - 1) / b near the
/// top of T's range.
template <class T>
constexpr T ceil_div(T a, T b) {
  static_assert(bits_detail::kUnsigned<T>, "ceil_div takes unsigned integers");
  return static_cast<T>(a / b + (a % b != 0 ? 1 : 0));
}

/// x with its 32 bits in reverse order (bit 0 <-> bit 31).
inline constexpr uint32_t reverse_bits32(uint32_t x) {
  x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
  x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
  x = ((x >> 4) & 0x0F0F0F0Fu) | ((x & 0x0F0F0F0Fu) << 4);
  x = ((x >> 8) & 0x00FF00FFu) | ((x & 0x00FF00FFu) << 8);
  return (x >> 16) | (x << 16);
}

/// The low m bits of x in reverse order (bit 0 <-> bit m - 1), for
/// 0 <= m <= 32; higher bits of x are ignored. The base-2 radical inverse of
/// x as an m-bit integer: reverse_low_bits(1, 3) = 0b100.
inline constexpr uint32_t reverse_low_bits(uint32_t x, int m) { return m <= 0 ? 0 : reverse_bits32(x) >> (32 - m); }

/// The low `bits` bits set: low_mask(3) = 0b111; 0 for bits <= 0, all 64
/// for bits >= 64.
inline constexpr uint64_t low_mask(int bits) {
  return bits <= 0 ? 0 : bits >= 64 ? ~uint64_t{0} : (uint64_t{1} << bits) - 1;
}

}  // namespace ropsim
