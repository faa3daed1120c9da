// The libFuzzer entry point of one target, chosen at compile time
// (-DROPSIM_FUZZ_ENTRY=fuzz_trace, ...; fuzz/CMakeLists.txt).
#include "fuzz_targets.h"

#ifndef ROPSIM_FUZZ_ENTRY
#error "ROPSIM_FUZZ_ENTRY must name the target function"
#endif

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return ropsim_fuzz::ROPSIM_FUZZ_ENTRY(data, size);
}
