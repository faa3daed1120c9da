// The set of cache lines DRAM holds (written back at least once), which fast
// clear consults on every read miss. A node-based hash set of line addresses
// cost a heap node and a cache miss per insert; this is a bitmap in pages of
// 4096 lines, allocated only for pages that are touched (state for touched
// tiles only), with recent pages remembered.
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <unordered_map>

#include "rtl_models/algo/bits.h"

namespace ropsim {

class LineSet {
 public:
  explicit LineSet(uint32_t line_bytes) : shift_(log2_ceil(line_bytes)) {}
  void insert(uint64_t line_addr) {
    const uint64_t i = line_addr >> shift_;
    (*page(i >> kPageBits, true))[(i >> 6) & (kWords - 1)] |= uint64_t{1} << (i & 63);
  }
  bool contains(uint64_t line_addr) const {
    const uint64_t i = line_addr >> shift_;
    const Page* p = const_cast<LineSet*>(this)->page(i >> kPageBits, false);
    return p && ((*p)[(i >> 6) & (kWords - 1)] >> (i & 63) & 1);
  }

 private:
  static constexpr int kPageBits = 12;  // 4096 lines a page
  static constexpr size_t kWords = (size_t{1} << kPageBits) / 64;
  using Page = std::array<uint64_t, kWords>;
  Page* page(uint64_t key, bool create) {
    // A small direct-mapped cache of recent pages (the three buffers and the
    // ROPs' tiles interleave, so one remembered page is not enough).
    Recent& r = recent_[(key ^ (key >> 29) ^ (key >> 36)) & (kRecent - 1)];
    if (r.page && r.key == key) return r.page;
    auto it = pages_.find(key);
    if (it == pages_.end()) {
      if (!create) return nullptr;
      it = pages_.emplace(key, std::make_unique<Page>()).first;
      it->second->fill(0);
    }
    r.key = key;
    r.page = it->second.get();
    return r.page;
  }
  struct Recent {
    uint64_t key = 0;
    Page* page = nullptr;
  };
  static constexpr size_t kRecent = 64;
  int shift_;
  std::unordered_map<uint64_t, std::unique_ptr<Page>> pages_;
  std::array<Recent, kRecent> recent_{};
};

}  // namespace ropsim
