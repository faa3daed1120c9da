#include "util/memory_budget.h"

#include <unistd.h>

#include <cctype>
#include <charconv>
#include <cstdio>

#include "util/errors.h"

namespace ropsim {

void MemoryBudget::charge(uint64_t bytes, const char* what) {
  const uint64_t now = used_.fetch_add(bytes, std::memory_order_relaxed) + bytes;
  if (limit_ != 0 && now > limit_) {
    used_.fetch_sub(bytes, std::memory_order_relaxed);
    refuse(now, what, "grew to");
  }
  for (uint64_t p = peak_.load(std::memory_order_relaxed);
       now > p && !peak_.compare_exchange_weak(p, now, std::memory_order_relaxed);) {
  }
}

void MemoryBudget::check_estimate(uint64_t bytes, const std::string& what) const {
  if (limit_ != 0 && bytes > limit_) refuse(bytes, what, "is estimated to need");
}

void MemoryBudget::refuse(uint64_t bytes, const std::string& what, const char* how) const {
  throw UserError("memory limit: the run's state " + std::string(how) + " " + format_bytes(bytes) + " (" + what +
                  "), over --memory-limit " + format_bytes(limit_) +
                  " (default 80 % of physical memory; raise it, or use a smaller screen, spp or trace)");
}

MemoryBudget& memory_budget() {
  static MemoryBudget* b = [] {
    auto* m = new MemoryBudget();  // never destroyed: charged from static destructors too
    m->set_limit(default_memory_limit());
    return m;
  }();
  return *b;
}

namespace {
uint64_t physical_memory() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  return pages > 0 && page > 0 ? uint64_t(pages) * uint64_t(page) : 0;
}
}  // namespace

uint64_t default_memory_limit() { return physical_memory() / 5 * 4; }

uint64_t parse_memory_size(const std::string& text, const std::string& flag) {
  auto bad = [&] {
    throw UserError(flag + " \"" + text +
                    "\": expected bytes with an optional K, M, G or T suffix (binary), a percentage of physical "
                    "memory such as 50%, or none");
  };
  if (text == "none") return 0;
  uint64_t v = 0;
  const char* first = text.data();
  const char* last = text.data() + text.size();
  const auto r = std::from_chars(first, last, v);
  if (r.ec != std::errc() || r.ptr == first) bad();
  const std::string suffix(r.ptr, last);
  if (v == 0)
    throw UserError(flag + " \"" + text + "\": a limit of 0 leaves no memory to run in; for no limit give none");
  if (suffix == "%") {
    if (v == 0 || v > 100) bad();
    return physical_memory() / 100 * v;
  }
  int shift = 0;
  if (suffix.empty() || suffix == "B") {
    shift = 0;
  } else if (suffix.size() <= 3 && (suffix.size() == 1 || suffix.substr(1) == "iB" || suffix.substr(1) == "B")) {
    switch (std::toupper(static_cast<unsigned char>(suffix[0]))) {
      case 'K':
        shift = 10;
        break;
      case 'M':
        shift = 20;
        break;
      case 'G':
        shift = 30;
        break;
      case 'T':
        shift = 40;
        break;
      default:
        bad();
    }
  } else {
    bad();
  }
  if (v > (UINT64_MAX >> shift)) bad();
  return v << shift;
}

std::string format_bytes(uint64_t b) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  double v = double(b);
  while (v >= 1024.0 && u < 4) v /= 1024.0, ++u;
  char buf[32];
  if (u == 0)
    std::snprintf(buf, sizeof buf, "%llu B", static_cast<unsigned long long>(b));
  else
    std::snprintf(buf, sizeof buf, "%.1f %s", v, units[u]);
  return buf;
}

}  // namespace ropsim
