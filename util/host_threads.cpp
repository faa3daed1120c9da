#include "util/host_threads.h"

#include <sched.h>

#include <atomic>
#include <thread>

namespace ropsim {

namespace {
std::atomic<int> g_threads{0};  // 0: not set
}

int available_cores() {
  cpu_set_t set;
  if (sched_getaffinity(0, sizeof set, &set) == 0) {
    const int n = CPU_COUNT(&set);
    if (n > 0) return n;
  }
  const unsigned n = std::thread::hardware_concurrency();
  return n > 0 ? int(n) : 1;
}

int host_threads() {
  const int n = g_threads.load(std::memory_order_relaxed);
  return n > 0 ? n : available_cores();
}

void set_host_threads(int n) { g_threads.store(n > 0 ? n : 1, std::memory_order_relaxed); }

}  // namespace ropsim
