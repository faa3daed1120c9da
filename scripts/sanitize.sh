#!/usr/bin/env bash
# The sanitizer build (docs/testing.md "Sanitizers"): every target built by
# clang with AddressSanitizer and UndefinedBehaviorSanitizer in build-asan/
# (scripts/asan_build.sh, shared with the fuzz targets), any report fatal,
# then the test suite run under them. The bit-exact matrix
# runs on the default design only (the other designs are the same code on
# other timing parameters; the full matrix runs in the normal build), and the
# SLURM test is left to the normal build (its daemons are not ropsim's code).
#
#   scripts/sanitize.sh [CTEST ARGS...]
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/scripts/asan_build.sh"
b="$root/build-asan"
bash "$root/scripts/ctest_cost.sh" seed "$b"
cd "$b"
# SystemC switches coroutine stacks, which ASan cannot follow for
# use-after-return, and LeakSanitizer's exit-time scan of a process that ran
# SystemC coroutines crashes ("Tracer caught signal 11"): leaks are checked by
# the fuzz targets (scripts/fuzz.sh, no SystemC), not here.
export ASAN_OPTIONS="detect_stack_use_after_return=0:detect_leaks=0:abort_on_error=1:halt_on_error=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
# Reduced where the plain suite already covers it: the bit-exact matrix's
# narrow and wide designs and, on the default design, all but three small
# scenes (testcard and the two Enderton scenes still run every method and spp
# through compression and Hi-Z), the uncompressed and fit-encoder matrix
# (BitExactCompression: the uncompressed path runs here in the tests that
# turn compression off, the fit encoder in Compression.*), SLURM, the thread-count check on the four
# largest scenes (the four small ones still run every method and spp), and the
# fidelity study (the full cycle model on the motor three times) and the
# README's command block (the same verbs, each tested on its own here), and
# the two digests (value checks over every scene, method and design: the
# plain suite runs them; the code paths they take run here in the other
# tests), the Enderton examples (value checks of the golden model, whose code
# every bit-exact test here runs), the run of every help text's examples (the
# verbs' code runs here in their own tests) and the report rendered in
# chromium (chromium's code; the report's writer runs in the other StudyReport
# tests), and the check of docs/results.md's figures (ResultsDoc: the same
# ropsim runs as the tests above, compared with the committed text). The
# RTL testbenches (RTL.*) are Verilator's and Yosys's code, not ropsim's: the
# sanitizer build does not build them (tests/CMakeLists.txt), and the
# pattern keeps them out should a build-asan/ from before have them.
ctest --output-on-failure -j "$(nproc)" \
  -E 'RTL\.|TimingDigest|GoldenDigest|EndertonExamples|Cli\.EveryVerbsHelpHasExamplesThatRun|StudyReport\.ASmallStudysReportIsSelfContainedAndRendersInChromium|BitExact\..*_(narrow|wide)|BitExact\..*/(eight_layers|cloth|smoke|opaque|foliage)_default|BitExactCompression|SlurmStudy|StudySlurm|FidelityStudy|Readme\.UsingIt|ResultsDoc|Decoupling\.EqualsLockstepExactlyWithCompression|GoldenThreads\..*/(cloth|smoke|opaque|foliage)( |$)' "$@"
