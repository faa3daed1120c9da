// Comparisons that name the first difference, for tests that compare whole
// images, byte buffers, sequences, draw tables or structs: each returns "" when the two
// are equal and otherwise where they first differ and both values, so that
// EXPECT_EQ(first_image_difference(a, b), "") prints what differs.
#pragma once
#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <iterator>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "rtl_models/functional/image.h"
#include "traces/format/draw_state.h"

namespace ropsim_test {

/// A value as a test prints it: numbers as numbers (floats to 9 digits with
/// their bits), enumerations as their number, strings quoted, arrays and
/// vectors element by element.
inline std::string show(float v) {
  uint32_t bits = 0;
  std::memcpy(&bits, &v, 4);
  char s[48];
  std::snprintf(s, sizeof s, "%.9g (0x%08x)", double(v), unsigned(bits));
  return s;
}
inline std::string show(double v) {
  uint64_t bits = 0;
  std::memcpy(&bits, &v, 8);
  char s[64];
  std::snprintf(s, sizeof s, "%.17g (0x%016llx)", v, static_cast<unsigned long long>(bits));
  return s;
}
inline std::string show(const std::string& v) { return "\"" + v + "\""; }
inline std::string show(bool v) { return v ? "true" : "false"; }
template <class T>
std::string show(const T& v);
template <class T, size_t N>
std::string show(const std::array<T, N>& v) {
  std::string s = "{";
  for (size_t i = 0; i < N; ++i) s += (i ? ", " : "") + show(v[i]);
  return s + "}";
}
template <class T>
std::string show(const std::vector<T>& v) {
  std::string s = "{";
  for (size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + show(v[i]);
  return s + "}";
}
template <class T>
std::string show(const T& v) {
  if constexpr (std::is_enum_v<T>) {
    return std::to_string(static_cast<long long>(v));
  } else if constexpr (std::is_integral_v<T>) {
    return std::to_string(v);  // uint8_t too, as a number
  } else {
    std::ostringstream o;
    o << v;
    return o.str();
  }
}

/// Compares named fields in turn and keeps the first that differs:
///   ASSERT_EQ(Fields().eq("x", a.x, b.x).eq("y", a.y, b.y).str(), "");
/// eq compares with ==, bits compares the object representations (memcmp).
class Fields {
 public:
  template <class T>
  Fields& eq(const char* name, const T& a, const T& b) {
    if (diff_.empty() && !(a == b)) diff_ = std::string(name) + ": " + show(a) + " vs " + show(b);
    return *this;
  }
  template <class T>
  Fields& bits(const char* name, const T& a, const T& b) {
    static_assert(std::is_trivially_copyable_v<T>);
    if (diff_.empty() && std::memcmp(&a, &b, sizeof(T)) != 0)
      diff_ = std::string(name) + " (bits): " + show(a) + " vs " + show(b);
    return *this;
  }
  const std::string& str() const { return diff_; }

 private:
  std::string diff_;
};

/// The first difference between two images as operator== sees them (the
/// sizes, then every pixel's channels bit for bit): the pixel, its channel
/// and both values.
inline std::string first_image_difference(const ropsim::Image& a, const ropsim::Image& b) {
  if (a.width != b.width || a.height != b.height)
    return "sizes " + std::to_string(a.width) + " x " + std::to_string(a.height) + " vs " + std::to_string(b.width) +
           " x " + std::to_string(b.height);
  std::vector<float> ra(size_t(a.width) * 3), rb(ra.size());
  for (uint32_t y = 0; y < a.height; ++y) {
    a.row(y, ra.data());
    b.row(y, rb.data());
    if (std::memcmp(ra.data(), rb.data(), ra.size() * sizeof(float)) == 0) continue;
    for (size_t i = 0; i < ra.size(); ++i)
      if (std::memcmp(&ra[i], &rb[i], sizeof(float)) != 0)
        return "pixel (" + std::to_string(i / 3) + ", " + std::to_string(y) + ") channel " + "rgb"[i % 3] + ": " +
               show(ra[i]) + " vs " + show(rb[i]);
  }
  return "";
}

/// The first byte at which two buffers differ, with both bytes, or their
/// sizes when one is the start of the other.
inline std::string first_byte_difference(const std::string& a, const std::string& b) {
  const size_t n = std::min(a.size(), b.size());
  for (size_t i = 0; i < n; ++i)
    if (a[i] != b[i]) {
      char s[128];
      std::snprintf(s, sizeof s, "byte %zu: 0x%02x vs 0x%02x (sizes %zu and %zu)", i, unsigned(uint8_t(a[i])),
                    unsigned(uint8_t(b[i])), a.size(), b.size());
      return s;
    }
  if (a.size() != b.size())
    return "sizes " + std::to_string(a.size()) + " vs " + std::to_string(b.size()) + " (the first " +
           std::to_string(n) + " bytes equal)";
  return "";
}

/// The first index at which two sequences (containers or arrays) differ,
/// floating-point elements bit for bit (as memcmp compares them) and others
/// with ==, with both elements; or their sizes when one is the start of the other.
template <class A, class B>
std::string first_element_difference(const A& a, const B& b) {
  const size_t na = std::size(a), nb = std::size(b), n = std::min(na, nb);
  auto ia = std::begin(a);
  auto ib = std::begin(b);
  for (size_t i = 0; i < n; ++i, ++ia, ++ib) {
    using T = std::decay_t<decltype(*ia)>;
    bool same = false;
    if constexpr (std::is_floating_point_v<T>)
      same = std::memcmp(&*ia, &*ib, sizeof(T)) == 0;
    else
      same = *ia == *ib;
    if (!same)
      return "element " + std::to_string(i) + ": " + show(*ia) + " vs " + show(*ib) + " (sizes " + std::to_string(na) +
             " and " + std::to_string(nb) + ")";
  }
  if (na != nb)
    return "sizes " + std::to_string(na) + " vs " + std::to_string(nb) + " (the first " + std::to_string(n) +
           " elements equal)";
  return "";
}

/// The first field of the first draw state at which two draw tables differ
/// (the fields DrawTable::operator== compares), or their sizes.
inline std::string first_draw_table_difference(const ropsim::DrawTable& ta, const ropsim::DrawTable& tb) {
  const auto &a = ta.states(), &b = tb.states();
  if (a.size() != b.size()) return "sizes " + std::to_string(a.size()) + " vs " + std::to_string(b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    const ropsim::DrawState &x = a[i], &y = b[i];
    const std::string d = Fields()
                              .eq("draw_id", x.draw_id, y.draw_id)
                              .eq("blend", x.blend, y.blend)
                              .eq("eq_rgb", x.eq_rgb, y.eq_rgb)
                              .eq("eq_alpha", x.eq_alpha, y.eq_alpha)
                              .eq("src_rgb", x.src_rgb, y.src_rgb)
                              .eq("dst_rgb", x.dst_rgb, y.dst_rgb)
                              .eq("src_alpha", x.src_alpha, y.src_alpha)
                              .eq("dst_alpha", x.dst_alpha, y.dst_alpha)
                              .eq("blend_color", x.blend_color, y.blend_color)
                              .eq("depth_test", x.depth_test, y.depth_test)
                              .eq("depth_func", x.depth_func, y.depth_func)
                              .eq("depth_write", x.depth_write, y.depth_write)
                              .eq("color_mask", x.color_mask, y.color_mask)
                              .eq("encoding", x.encoding, y.encoding)
                              .eq("name", x.name, y.name)
                              .str();
    if (!d.empty()) return "draw state " + std::to_string(i) + " (draw " + std::to_string(x.draw_id) + "): " + d;
  }
  return "";
}

}  // namespace ropsim_test
