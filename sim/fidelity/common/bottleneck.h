// What bounds a frame's time, classified from a timing model's own bounds.
// Every fidelity (cycle, sampled, approximate) lists its resources' bounds
// and calls the one rule here; docs/reports.md ("The bottleneck") gives the
// formula and the threshold. No SystemC: the analytical model uses it too.
#pragma once
#include <string>
#include <vector>

namespace ropsim {

/// One resource's own lower bound on the frame's cycles.
struct ResourceBound {
  enum class Kind {
    kThroughput,  ///< a unit: its busy cycles (its work at its issue rate)
    kBandwidth,   ///< the DRAM: its busiest channel's service of the frame's bursts
  };
  std::string name;  ///< the unit kind (trace_source, depth_test, ...) or "dram"
  Kind kind = Kind::kThroughput;
  double cycles = 0;  ///< the bound, cycles
};

/// A resource whose bound is at least this share of the frame's cycles
/// bounds the frame (the frame takes at most 1 / 0.8 = 1.25 x its bound).
constexpr double kBoundShare = 0.8;

struct Bottleneck {
  enum class Kind {
    kThroughput,  ///< a unit's busy cycles bound the frame
    kBandwidth,   ///< the DRAM's service of its bursts bounds the frame
    kLatency,     ///< no bound reaches kBoundShare of the frame: waiting on misses and round trips dominates
  };
  Kind kind = Kind::kLatency;
  std::string resource;               ///< the resource with the largest bound ("" when there is none)
  double bound_cycles = 0;            ///< its bound, cycles
  double frame_cycles = 0;            ///< the frame's cycles the bounds are compared with
  std::vector<ResourceBound> bounds;  ///< every resource's bound, largest first (ties: in the order given)
  /// The largest bound's share of the frame, in [0, inf).
  double share() const { return frame_cycles > 0 ? bound_cycles / frame_cycles : 0.0; }
};

/// "throughput", "bandwidth" or "latency".
const char* to_string(Bottleneck::Kind k);
/// "throughput" or "bandwidth".
const char* to_string(ResourceBound::Kind k);

/// The rule, for every fidelity: the resource r with the largest bound B_r
/// (the first of equal ones in the order given); when B_r >= kBoundShare x
/// frame_cycles, r's kind (throughput for a unit, bandwidth for the DRAM)
/// names r, otherwise the frame is latency-bound. Bounds of 0 are dropped.
Bottleneck classify_bottleneck(std::vector<ResourceBound> bounds, double frame_cycles);

/// The bottleneck as one line, "CLASS: why" (the class before the first ':'
/// is "throughput (UNIT)", "bandwidth (dram)" or "latency"), e.g.
/// "bandwidth (dram): bound 960 of the frame's 1000 cycles (96 %)".
std::string format_bottleneck(const Bottleneck& b);
/// Every bound, largest first: "dram 960 (96 %), depth_test 120 (12 %)".
std::string format_bounds(const Bottleneck& b);

}  // namespace ropsim
