// A fixed-length array allocated a page at a time, on first access through
// operator[]: per-tile state over a screen costs memory for the tiles a frame
// touches, not for width x height. get() of a page never allocated gives the
// fill value. Each page is charged to the run's memory budget (--memory-limit)
// when it is allocated.
#pragma once
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "util/memory_budget.h"

namespace ropsim {

template <class T>
class PagedArray {
 public:
  using value_type = T;
  static constexpr int kPageShift = 12;  ///< 4,096 entries a page
  static constexpr size_t kPage = size_t{1} << kPageShift;

  /// n entries, each `fill`; no page is allocated. `what` names the state
  /// in a memory-limit error.
  void assign(size_t n, const T& fill, const char* what) {
    n_ = n;
    fill_ = fill;
    what_ = what;
    pages_.clear();
    pages_.resize((n + kPage - 1) >> kPageShift);
    allocated_ = 0;
    mem_.reset();
  }
  size_t size() const { return n_; }
  /// Entry i, its page allocated (filled) on first access.
  T& operator[](size_t i) {
    std::unique_ptr<T[]>& p = pages_[i >> kPageShift];
    if (!p) {
      mem_.add(page_bytes(), what_);
      p = std::make_unique<T[]>(kPage);
      std::fill_n(p.get(), kPage, fill_);
      ++allocated_;
    }
    return p[i & (kPage - 1)];
  }
  /// Entry i; the fill value if its page was never allocated.
  const T& get(size_t i) const {
    const std::unique_ptr<T[]>& p = pages_[i >> kPageShift];
    return p ? p[i & (kPage - 1)] : fill_;
  }
  /// Pages allocated so far.
  size_t pages() const { return allocated_; }
  /// Host bytes of a page and of the page table's entry per page.
  static constexpr size_t page_bytes() { return kPage * sizeof(T); }
  static constexpr size_t table_bytes_per_page() { return sizeof(std::unique_ptr<T[]>); }
  /// Every entry, as a flat vector.
  std::vector<T> to_vector() const {
    std::vector<T> v(n_, fill_);
    for (size_t p = 0; p < pages_.size(); ++p)
      if (pages_[p])
        std::copy_n(pages_[p].get(), std::min(kPage, n_ - p * kPage), v.begin() + std::ptrdiff_t(p * kPage));
    return v;
  }

 private:
  std::vector<std::unique_ptr<T[]>> pages_;
  size_t n_ = 0, allocated_ = 0;
  T fill_{};
  const char* what_ = "";
  BudgetShare mem_;
};

}  // namespace ropsim
