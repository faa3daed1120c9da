// ROPSIM_TEST_ASAN is defined when the tests are built with AddressSanitizer
// (GCC's __SANITIZE_ADDRESS__ or Clang's __has_feature): the memory tests
// then skip what its shadow memory and quarantine make unmeasurable.
#pragma once

#if defined(__SANITIZE_ADDRESS__)
#define ROPSIM_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define ROPSIM_TEST_ASAN 1
#endif
#endif
