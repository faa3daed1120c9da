// The version (CMake project version) and the source commit (`git describe
// --always --dirty` when built, "unknown" outside a git checkout).
#pragma once

namespace ropsim {

const char* ropsim_version();
const char* ropsim_commit();

}  // namespace ropsim
