// Coverage-bitmask surface tracker of LK 2011 §2 and Figure 7 lines 4-8, 18.
#pragma once
#include <cstdint>

#include "rtl_models/algo/numerics.h"

namespace ropsim {

/// Bytes of one pixel's tracker state in the ROP's buffer: the covered mask
/// (spp bits) and the surface id, rounded up to whole bytes.
constexpr uint32_t tracker_state_bytes(int spp, int surface_id_bits) {
  return uint32_t(spp + surface_id_bits + 7) / 8u;
}

/// Per-pixel tracker state: the current surface id and the samples it covers.
struct TrackerState {
  uint64_t covered = 0;
  uint32_t surface_id = 0;
  bool operator==(const TrackerState& o) const { return covered == o.covered && surface_id == o.surface_id; }
};

struct TrackResult {
  uint32_t n = 0;           ///< first sequence index for this fragment: popcount(covered)
  uint32_t surface_id = 0;  ///< surface id to hash with
  bool new_surface = false;
};

/// Lines 4-8: if the depth-surviving samples S touch a covered bit, start a new
/// surface (surface id + 1 modulo 2^surface_id_bits, clear the mask).
/// Returns n = popcount(covered) after that decision. Line 18 is track_commit.
inline TrackResult track_surface(TrackerState& t, uint64_t surviving, int surface_id_bits) {
  TrackResult r;
  if (surviving & t.covered) {
    t.surface_id = static_cast<uint32_t>((uint64_t{t.surface_id} + 1) & low_mask(surface_id_bits));
    t.covered = 0;
    r.new_surface = true;
  }
  r.n = static_cast<uint32_t>(__builtin_popcountll(t.covered));
  r.surface_id = t.surface_id;
  return r;
}

/// Line 18: mark the surviving samples as covered by the current surface.
inline void track_commit(TrackerState& t, uint64_t surviving) { t.covered |= surviving; }

}  // namespace ropsim
