#include "util/version.h"

#include "ropsim_version.h"  // generated into the build tree by cmake/version.cmake

namespace ropsim {

const char* ropsim_version() { return ROPSIM_VERSION; }
const char* ropsim_commit() { return ROPSIM_COMMIT; }

}  // namespace ropsim
