// The memory a run's growing state may take (--memory-limit).
//
// What grows with the input -- the per-sample buffers of the tiles a scene
// touches, the resolved image's tiles, the A-buffer reference's fragment
// lists -- is charged here as it is allocated, and released when freed. A
// charge that would take the total over the limit is refused with a one-line
// UserError naming what needed it and the limit, never std::bad_alloc. A run
// also checks its estimated need up front (check_estimate) and is refused
// before any work when that is already over.
//
// The default limit is 80 % of physical memory. One budget per process:
// parallel simulations are processes (SystemC), each with its own. Bottom
// layer: the standard library only.
#pragma once
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <string>

namespace ropsim {

class MemoryBudget {
 public:
  /// The limit in bytes; 0: no limit.
  void set_limit(uint64_t bytes) { limit_ = bytes; }
  uint64_t limit() const { return limit_; }
  /// Takes bytes for `what` ("the A-buffer reference"); throws UserError if
  /// that would exceed the limit (nothing is taken then).
  void charge(uint64_t bytes, const char* what);
  void charge(uint64_t bytes, const std::string& what) { charge(bytes, what.c_str()); }
  void release(uint64_t bytes) { used_.fetch_sub(bytes, std::memory_order_relaxed); }
  /// Refuses a run whose estimated need (bytes, for `what`) is over the limit.
  void check_estimate(uint64_t bytes, const std::string& what) const;
  uint64_t used() const { return used_.load(std::memory_order_relaxed); }
  uint64_t peak() const { return peak_.load(std::memory_order_relaxed); }

 private:
  [[noreturn]] void refuse(uint64_t bytes, const std::string& what, const char* how) const;
  uint64_t limit_ = 0;
  std::atomic<uint64_t> used_{0}, peak_{0};
};

/// The process's budget (its limit set once by the CLI, default_memory_limit() until then).
MemoryBudget& memory_budget();

/// 80 % of physical memory (sysconf), in bytes.
uint64_t default_memory_limit();

/// A memory size: a whole number of bytes with an optional binary suffix
/// K, M, G or T (KiB ... TiB), or a percentage of physical memory ("50%"),
/// or "none" for no limit (returned as 0). Throws UserError naming `flag` on
/// anything else, "" and a zero size (0, 0M, 0%) included.
uint64_t parse_memory_size(const std::string& text, const std::string& flag);

/// "1.5 GiB", "640 MiB", "12 KiB", "100 B".
std::string format_bytes(uint64_t bytes);

/// The bytes an owner holds in the budget, released when it is destroyed
/// (movable, so containers that own one can move).
class BudgetShare {
 public:
  BudgetShare() = default;
  BudgetShare(BudgetShare&& o) noexcept : bytes_(o.bytes_) { o.bytes_ = 0; }
  BudgetShare& operator=(BudgetShare&& o) noexcept {
    if (this != &o) {
      reset();
      bytes_ = o.bytes_;
      o.bytes_ = 0;
    }
    return *this;
  }
  BudgetShare(const BudgetShare&) = delete;
  BudgetShare& operator=(const BudgetShare&) = delete;
  ~BudgetShare() { reset(); }
  void add(uint64_t bytes, const char* what) {
    memory_budget().charge(bytes, what);
    bytes_ += bytes;
  }
  void add(uint64_t bytes, const std::string& what) { add(bytes, what.c_str()); }
  void reset() {
    if (bytes_) memory_budget().release(bytes_);
    bytes_ = 0;
  }
  uint64_t bytes() const { return bytes_; }
  /// Takes over what o holds (no charge: the bytes change owner).
  void take(BudgetShare& o) {
    bytes_ += o.bytes_;
    o.bytes_ = 0;
  }

 private:
  uint64_t bytes_ = 0;
};

}  // namespace ropsim
