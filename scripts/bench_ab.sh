#!/usr/bin/env bash
# A/B host-speed benchmark (not a test): builds git revision BASE (default:
# the first parent of HEAD) beside this checkout and runs both sides'
# benchmarks alternately, ROUNDS times (default 5), on the same trace in one
# run: the cycle model's simulated fragments per host second on cloth at 16
# spp (ropsim_bench_cycle, default config), the golden model's on the same
# trace file as a user runs it (`ropsim run --threads 1`, its own process, so
# that no other model's heap is left behind in it) and the golden model alone
# on in-memory fragments (ropsim_bench, BM_Golden); and the cycle model on the
# captured motor (traces/scenes/mesh/motor.toml: 1920 x 1080, 16 spp, each
# side's trace captured by its own build from its own scene file, the meshes
# from ROPSIM_MESH_DIR or ../shared/data/meshes; its `ropsim run --fidelity
# cycle` report's host.simulated_fragments_per_second, sc_start alone).
# ROPSIM_AB_MOTOR=0 leaves the motor out (it takes some 20 s a round).
# Prints min / median / max of each figure per side and the median ratio.
# With HEAD_REV, the head side is that revision, built the same way, instead
# of this checkout (to measure one past change alone).
#   scripts/bench_ab.sh edd19d5 7
#   scripts/bench_ab.sh 19667d5 7 1d1f08d
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
base_rev="${1:-HEAD~1}"
rounds="${2:-5}"
head_rev="${3:-}"
# Builds revision $1's benchmarks in build-ab/<sha>/build; prints that folder.
build_rev() {
  local sha ab
  sha="$(git -C "$root" rev-parse --short=12 "$1")"
  ab="$root/build-ab/$sha"
  if [ ! -x "$ab/build/ropsim_bench_cycle" ] || [ ! -x "$ab/build/ropsim" ]; then
    rm -rf "$ab/src"
    mkdir -p "$ab"
    git -C "$root" archive "$sha" | (mkdir -p "$ab/src" && tar -x -C "$ab/src")
    cmake -S "$ab/src" -B "$ab/build" -DCMAKE_BUILD_TYPE=Release -DROPSIM_BUILD_TESTS=OFF >/dev/null
    cmake --build "$ab/build" -j "$(nproc)" --target ropsim ropsim_bench ropsim_bench_cycle >/dev/null
  fi
  echo "$ab/build"
}
base_sha="$(git -C "$root" rev-parse --short=12 "$base_rev")"
bash "$root/scripts/deps.sh" >/dev/null
base_dir="$(build_rev "$base_rev")"
if [ -n "$head_rev" ]; then
  head_dir="$(build_rev "$head_rev")"
  head_sha="$(git -C "$root" rev-parse --short=12 "$head_rev")"
else
  bash "$root/scripts/build.sh" >/dev/null
  head_dir="$root/build"
  head_sha="$(git -C "$root" rev-parse --short=12 HEAD)"
fi
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
motor="${ROPSIM_AB_MOTOR:-1}"
meshes="${ROPSIM_MESH_DIR:-$root/../shared/data/meshes}"
if [ "$motor" = 1 ]; then
  # Each side's motor trace, from its own sources (the trace format may differ).
  base_src="$(dirname "$base_dir")/src"
  head_src="$root"
  [ -n "$head_rev" ] && head_src="$(dirname "$head_dir")/src"
  for side in base head; do
    dir="$head_dir" src="$head_src"
    [ "$side" = base ] && dir="$base_dir" src="$base_src"
    (cd "$src" && "$dir/ropsim" capture traces/scenes/mesh/motor.toml --mesh-dir "$meshes" -o "$out/motor-$side.rtr" >/dev/null)
  done
fi
for ((i = 0; i < rounds; ++i)); do
  for side in base head; do
    dir="$head_dir"
    [ "$side" = base ] && dir="$base_dir"
    "$dir/ropsim_bench_cycle" --benchmark_filter=bitonic --benchmark_format=json >"$out/$side-cycle-$i.json" 2>/dev/null
    # The trace the cycle benchmark wrote (bench/bench_cycle.cpp), read by the CLI.
    "$dir/ropsim" run --trace /tmp/ropsim-bench-cloth16.rtr --threads 1 --quiet --report "$out/$side-run-$i.json"
    "$dir/ropsim_bench" --benchmark_filter='Golden/(lk|opaque)/(16|64)' --benchmark_format=json \
      >"$out/$side-golden-$i.json" 2>/dev/null
    if [ "$motor" = 1 ]; then
      "$dir/ropsim" run --fidelity cycle --trace "$out/motor-$side.rtr" --quiet --report "$out/$side-motor-$i.json"
    fi
  done
done
/usr/bin/python3 - "$out" "$rounds" "$base_sha" "$head_sha" <<'PY'
import json, statistics, sys, glob, os
out, rounds, base, head = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
def figures(side):
    f = {}
    for i in range(rounds):
        for kind in ("cycle", "motor", "run", "golden"):
            path = os.path.join(out, f"{side}-{kind}-{i}.json")
            if kind == "motor" and not os.path.exists(path):
                continue
            doc = json.load(open(path))
            if kind == "motor":
                f.setdefault("cycle model, motor 1920x1080 16 spp [M frag/s]", []).append(
                    doc["host"]["simulated_fragments_per_second"] / 1e6)
                continue
            if kind == "run":
                f.setdefault("golden model from the trace file [M frag/s]", []).append(
                    doc["host"]["fragments_per_second"] / 1e6)
                continue
            for b in doc["benchmarks"]:
                if kind == "cycle":
                    f.setdefault("cycle model, cloth 16 spp [M frag/s]", []).append(b["cycle_frag_per_s"] / 1e6)
                else:
                    f.setdefault(f"{b['name']} in memory [M frag/s]", []).append(b["fragments_per_s"] / 1e6)
    return f
a, b = figures("base"), figures("head")
print(f"A/B over {rounds} alternating rounds: base {base}, head {head}")
print(f"{'figure':52} {'base min/med/max':>22} {'head min/med/max':>22} {'head/base':>9}")
for k in a:
    fa, fb = a[k], b[k]
    s = lambda v: f"{min(v):6.2f} {statistics.median(v):6.2f} {max(v):6.2f}"
    print(f"{k:52} {s(fa):>22} {s(fb):>22} {statistics.median(fb) / statistics.median(fa):9.3f}")
PY
