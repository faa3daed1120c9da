#include "sim/fidelity/common/bottleneck.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace ropsim {

const char* to_string(Bottleneck::Kind k) {
  switch (k) {
    case Bottleneck::Kind::kThroughput:
      return "throughput";
    case Bottleneck::Kind::kBandwidth:
      return "bandwidth";
    case Bottleneck::Kind::kLatency:
      return "latency";
  }
  return "?";
}

const char* to_string(ResourceBound::Kind k) {
  return k == ResourceBound::Kind::kBandwidth ? "bandwidth" : "throughput";
}

Bottleneck classify_bottleneck(std::vector<ResourceBound> bounds, double frame_cycles) {
  Bottleneck b;
  b.frame_cycles = frame_cycles;
  bounds.erase(std::remove_if(bounds.begin(), bounds.end(), [](const ResourceBound& r) { return !(r.cycles > 0); }),
               bounds.end());
  std::stable_sort(bounds.begin(), bounds.end(),
                   [](const ResourceBound& x, const ResourceBound& y) { return x.cycles > y.cycles; });
  b.bounds = std::move(bounds);
  if (b.bounds.empty()) return b;
  const ResourceBound& top = b.bounds.front();
  b.resource = top.name;
  b.bound_cycles = top.cycles;
  if (top.cycles >= kBoundShare * frame_cycles)
    b.kind = top.kind == ResourceBound::Kind::kBandwidth ? Bottleneck::Kind::kBandwidth : Bottleneck::Kind::kThroughput;
  return b;
}

namespace {
std::string cycles_text(double c) {
  char s[48];
  std::snprintf(s, sizeof s, "%.0f", std::round(c));
  return s;
}
std::string percent_text(double part, double whole) {
  char s[32];
  std::snprintf(s, sizeof s, "%.0f %%", whole > 0 ? 100.0 * part / whole : 0.0);
  return s;
}
}  // namespace

std::string format_bottleneck(const Bottleneck& b) {
  const std::string frame = cycles_text(b.frame_cycles);
  if (b.resource.empty()) return "latency: no resource has a bound over the frame's " + frame + " cycles";
  const std::string of = cycles_text(b.bound_cycles) + " of the frame's " + frame + " cycles (" +
                         percent_text(b.bound_cycles, b.frame_cycles) + ")";
  if (b.kind == Bottleneck::Kind::kLatency) {
    char at[16];
    std::snprintf(at, sizeof at, "%.0f %%", 100 * kBoundShare);
    return "latency: the largest bound, " + b.resource + " " + of + ", is below " + at +
           ": the frame waits on misses and round trips";
  }
  return std::string(to_string(b.kind)) + " (" + b.resource + "): bound " + of;
}

std::string format_bounds(const Bottleneck& b) {
  std::string s;
  for (const ResourceBound& r : b.bounds)
    s += (s.empty() ? "" : ", ") + r.name + " " + cycles_text(r.cycles) + " (" +
         percent_text(r.cycles, b.frame_cycles) + ")";
  return s.empty() ? "none" : s;
}

}  // namespace ropsim
