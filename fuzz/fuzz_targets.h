// The fuzz targets (docs/testing.md "Fuzzing"): each takes arbitrary bytes as
// one input file of its kind and runs it through what ropsim does with such a
// file. An input error (a std::runtime_error: TraceError, ConfigError,
// CaptureError, UserError, ...) is the expected outcome of a bad input and
// returns normally; anything else -- a crash, a sanitizer report, an
// InternalError, std::bad_alloc, an uncaught exception -- is a finding.
//
// Built two ways: as libFuzzer executables (clang, -DROPSIM_FUZZ=ON,
// scripts/fuzz.sh), and into the normal test suite, where
// FuzzRegressions.* replays the committed inputs of fuzz/regressions/.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace ropsim_fuzz {

/// A trace file (either payload encoding, version 1 or 2) read record by
/// record into the lk golden model, then resolved. A trace that reads whole
/// (up to 4096 fragments) must have a valid header and draw table, fragments
/// of the table's draws, and write and read back with the same header.
int fuzz_trace(const uint8_t* data, size_t size);
/// A mesh scene file, parsed and checked (the meshes it names are not loaded).
int fuzz_scene(const uint8_t* data, size_t size);
/// A hardware design file, then --hw-set overrides (the lines after a line
/// "%%"); a design that loads is printed, read back, and must be identical.
int fuzz_design(const uint8_t* data, size_t size);
/// A study file, parsed, checked and expanded into its points.
int fuzz_study(const uint8_t* data, size_t size);
/// A live-point library (docs/livepoints.md): an input that starts with the
/// magic is the file as it is; any other is taken as the payload and wrapped
/// in a valid header, checksum and zstd frame, so that the fuzzer reaches the
/// payload's parser. A library that reads must have every field in range (an
/// oracle written from docs/livepoints.md), and is written and read again,
/// and must give the same bytes.
int fuzz_livepoints(const uint8_t* data, size_t size);

/// The trace target's custom mutation (libfuzzer_entry.cpp): rewrites the
/// header's fragment count (bytes 42..47) by `seed` -- 0, 2^48 - 1, one bit
/// flipped, a few more or one fewer, a random count -- and recomputes the
/// header check, so that mutated counts reach the reader's bound on the
/// payload instead of stopping at the check.
void mutate_trace_count(uint8_t* data, size_t size, uint32_t seed);
/// Recomputes the header check of a trace whose header flags one (bit 1),
/// over the header's bytes (version 2: its draw table included).
void fix_trace_header_check(uint8_t* data, size_t size);
/// The trace target's mutation of the draw table (version 2): one field of
/// one draw record, chosen by `seed`, set to an end of its valid range, one
/// past it or the byte's ends (a draw id to its neighbours'; a blend colour
/// channel to NaN, infinity, -0...), and the header check recomputed, so that
/// mutated tables reach DrawTable::validate() instead of stopping at the check.
void mutate_trace_draws(uint8_t* data, size_t size, uint32_t seed);
/// The header's bytes before its check (version 2: the draw table included),
/// or 0 when the input is too short to hold them.
size_t trace_header_bytes(const uint8_t* data, size_t size);

struct Target {
  const char* name;
  int (*run)(const uint8_t*, size_t);
};
inline const std::vector<Target>& targets() {
  static const std::vector<Target> t = {
      {"trace", fuzz_trace}, {"scene", fuzz_scene}, {"design", fuzz_design}, {"study", fuzz_study},
      {"livepoints", fuzz_livepoints}};
  return t;
}

/// Writes the input to a file of this process (under $TMPDIR, or /tmp) with
/// the given suffix, for readers that take a path; returns the path.
std::string input_file(const uint8_t* data, size_t size, const char* suffix);

}  // namespace ropsim_fuzz
