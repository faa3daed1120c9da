// Cache hints: ask the host's memory system for the lines of a byte range, so
// that their misses overlap. A hint changes no state.
#pragma once
#include <cstddef>
#include <cstdint>

namespace ropsim {

/// Asks for every 64-byte line that [p, p + bytes) touches; ForWrite: the
/// caller will write them.
template <bool ForWrite = false>
inline void prefetch_lines(const void* p, size_t bytes) {
  const uintptr_t a = reinterpret_cast<uintptr_t>(p);
  for (uintptr_t q = a & ~uintptr_t{63}; q < a + bytes; q += 64)
    __builtin_prefetch(reinterpret_cast<const void*>(q), ForWrite ? 1 : 0);
}

}  // namespace ropsim
