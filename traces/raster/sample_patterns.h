// Sample positions: the D3D / Vulkan standard patterns for 1-16 spp and a
// documented (0,m,2)-net pattern for 32 and 64 spp (docs/trace-format.md).
#pragma once
#include <array>

#include "traces/format/trace.h"

namespace ropsim {

/// Positions in 1/256 pixel units from the pixel's top-left corner. An spp
/// with no standard pattern (not 1, 2, 4, ..., 64) is a UserError.
std::array<SamplePos, 64> standard_sample_positions(int spp);

}  // namespace ropsim
