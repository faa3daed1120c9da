#!/usr/bin/env bash
# Capture throughput: `ropsim capture` of a mesh scene (default: the motor-like
# 2CylinderEngine at 1920x1080, 16 spp), N runs (default 3), wall time of the
# whole command (mesh loading, shading, clipping, rasterization, zstd trace
# writing) and fragments per second. Target: motor 1920x1080 16 spp < 60 s.
# usage: scripts/bench_capture.sh [SCENE.toml] [RUNS] [extra ropsim capture flags]
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
scene="${1:-$root/traces/scenes/mesh/motor.toml}"
runs="${2:-3}"
shift $(( $# > 2 ? 2 : $# )) || true
ropsim="$root/build/ropsim"
[ -x "$ropsim" ] || bash "$root/scripts/build.sh" >/dev/null
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
for i in $(seq "$runs"); do
  start=$(date +%s.%N)
  line=$("$ropsim" capture "$scene" -o "$tmp/t.trace" "$@")
  end=$(date +%s.%N)
  frags=$(echo "$line" | sed -E 's/.* ([0-9]+) fragments.*/\1/')
  /usr/bin/python3 -c "import sys; t=float(sys.argv[2])-float(sys.argv[1]); f=int(sys.argv[3]); \
print(f'run {sys.argv[4]}: {t:.2f} s wall, {f} fragments, {f/t/1e6:.2f} M fragments/s, trace {int(sys.argv[5])/1e6:.1f} MB')" \
    "$start" "$end" "$frags" "$i" "$(stat -c %s "$tmp/t.trace")"
done
echo "$line"
