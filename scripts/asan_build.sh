#!/usr/bin/env bash
# The clang build shared by the sanitizer suite (scripts/sanitize.sh) and the
# fuzz targets (scripts/fuzz.sh), in build-asan/: every target with
# AddressSanitizer and UndefinedBehaviorSanitizer, any report fatal, and
# libFuzzer's coverage instrumentation (ROPSIM_FUZZ), so that the code is
# compiled under clang once for both. Installs clang, its runtimes and zstd
# if missing.
#
#   scripts/asan_build.sh [TARGET...]   # no target: every target
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/scripts/deps.sh"
need=()
for p in clang libclang-rt-14-dev zstd; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || need+=("$p")
done
if [ ${#need[@]} -gt 0 ]; then
  echo "asan build: installing ${need[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -q && apt-get install -y -q --no-install-recommends "${need[@]}"
fi
b="$root/build-asan"
# A folder configured before the fuzz targets joined it is configured again.
if ! grep -q '^ROPSIM_FUZZ:BOOL=ON' "$b/CMakeCache.txt" 2>/dev/null; then
  CXX=clang++ cmake -S "$root" -B "$b" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DROPSIM_FUZZ=ON \
    -DROPSIM_BUILD_BENCHMARKS=OFF >/dev/null
fi
targets=()
for t in "$@"; do targets+=(--target "$t"); done
cmake --build "$b" -j "$(nproc)" "${targets[@]}"
