#!/usr/bin/env bash
# Benchmarks (not tests): golden-model throughput in covered samples/s on one
# core for cloth at 16 and 64 spp, and peak memory of a 4K 64-spp screen with
# 10 % touched; the cycle model's simulated fragments per host second on cloth
# at 16 spp (default config) beside the functional model's. Extra args go to Google Benchmark (e.g. --benchmark_filter=lk).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/scripts/build.sh" >/dev/null
# Memory first, in its own process, so its peak RSS is its own.
"$root/build/ropsim_bench" --benchmark_filter=Memory "$@"
"$root/build/ropsim_bench" --benchmark_filter='Golden|RunScene' --benchmark_repetitions=3 \
  --benchmark_report_aggregates_only=true "$@"
"$root/build/ropsim_bench_cycle" --benchmark_repetitions=3 --benchmark_report_aggregates_only=true "$@"
