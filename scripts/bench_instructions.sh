#!/usr/bin/env bash
# Instruction-count A/B (not a test): builds the ropsim CLI of git revisions
# BASE and HEAD (default: this checkout's HEAD) in build-ab/<sha>/, then counts
# the instructions each executes (valgrind's cachegrind, no cache simulation)
# for the same golden-model runs: cloth at 16 and 64 spp, lk and opaque, from
# a trace file, report only. Instruction counts do not depend on what else the
# machine runs, so a cost of a few percent shows where host-time A/Bs
# (scripts/bench_ab.sh) drown in noise; they leave out cache and branch effects.
#   scripts/bench_instructions.sh 19667d5 1d1f08d
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
[ $# -ge 1 ] || { echo "usage: $0 BASE [HEAD]" >&2; exit 2; }
bash "$root/scripts/deps.sh" >/dev/null
command -v valgrind >/dev/null || {
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -q && apt-get install -y -q --no-install-recommends valgrind
}
build_rev() {
  local sha ab
  sha="$(git -C "$root" rev-parse --short=12 "$1")"
  ab="$root/build-ab/$sha"
  if [ ! -x "$ab/build/ropsim" ]; then
    if [ ! -d "$ab/src" ]; then
      mkdir -p "$ab/src"
      git -C "$root" archive "$sha" | tar -x -C "$ab/src"
    fi
    cmake -S "$ab/src" -B "$ab/build" -DCMAKE_BUILD_TYPE=Release -DROPSIM_BUILD_TESTS=OFF >/dev/null
    cmake --build "$ab/build" -j "$(nproc)" --target ropsim >/dev/null
  fi
  echo "$ab/build/ropsim"
}
base="$(build_rev "$1")"
head="$(build_rev "${2:-HEAD}")"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
for spp in 16 64; do "$head" scene cloth --spp "$spp" -o "$work/cloth$spp.rtr" >/dev/null; done
count() {
  valgrind --tool=cachegrind --cache-sim=no --cachegrind-out-file=/dev/null "$@" 2>&1 >/dev/null |
    sed -n 's/.*I *refs: *//p' | tr -d ,
}
# One thread: --threads exists from the golden model's threads on (a global flag).
one_thread() { if "$1" --help | grep -q -- --threads; then echo "--threads 1"; fi; }
printf '%-24s %16s %16s %9s\n' run "base instr" "head instr" head/base
for spp in 16 64; do
  for m in lk opaque; do
    args=(run --trace "$work/cloth$spp.rtr" --method "$m" --report "$work/r.json" --quiet)
    # shellcheck disable=SC2046
    b="$(count "$base" "${args[@]}" $(one_thread "$base"))"
    # shellcheck disable=SC2046
    h="$(count "$head" "${args[@]}" $(one_thread "$head"))"
    awk -v n="cloth $spp spp $m" -v b="$b" -v h="$h" 'BEGIN { printf "%-24s %16d %16d %9.4f\n", n, b, h, h / b }'
  done
done
