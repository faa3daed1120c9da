// The libFuzzer entry point of one target, chosen at compile time
// (-DROPSIM_FUZZ_ENTRY=fuzz_trace, ...; fuzz/CMakeLists.txt).
#include "fuzz/fuzz_targets.h"

#ifndef ROPSIM_FUZZ_ENTRY
#error "ROPSIM_FUZZ_ENTRY must name the target function"
#endif

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return ropsim_fuzz::ROPSIM_FUZZ_ENTRY(data, size);
}

#ifdef ROPSIM_FUZZ_TRACE_MUTATOR
// The trace target: libFuzzer's mutations, then, one time in four, a new
// fragment count (mutate_trace_count), one time in four a draw record's field
// (mutate_trace_draws, version 2), else a header check made to match one time
// in two, so mutations of the header's fields reach their checks.
extern "C" size_t LLVMFuzzerMutate(uint8_t* data, size_t size, size_t max_size);
extern "C" size_t LLVMFuzzerCustomMutator(uint8_t* data, size_t size, size_t max_size, unsigned int seed) {
  size = LLVMFuzzerMutate(data, size, max_size);
  if (seed % 4 == 0)
    ropsim_fuzz::mutate_trace_count(data, size, seed / 4);
  else if (seed % 4 == 2)
    ropsim_fuzz::mutate_trace_draws(data, size, seed / 4);
  else if (seed % 2 == 1)
    ropsim_fuzz::fix_trace_header_check(data, size);
  return size;
}
#endif
