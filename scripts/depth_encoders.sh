#!/usr/bin/env bash
# The two depth encoders side by side (docs/results.md "Rasterizer planes
# against fitted planes"): the final depth buffer's compressed bytes
# (`ropsim run --fidelity functional --compressibility` on the default
# design, its `compressibility` report) with compression.depth_encoder = plane and fit,
# for opaque and lk on cloth at 4, 16 and 64 spp and on the captured motor
# (1920 x 1080, 16 spp). Prints a Markdown table; about 20 s.
# usage: scripts/depth_encoders.sh
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
ropsim="$root/build/ropsim"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
"$ropsim" capture "$root/traces/scenes/mesh/motor.toml" -o "$work/motor.rtr" >/dev/null
depth_bytes() {  # INPUT-ARGS METHOD ENCODER -> "uncompressed compressed"
  # shellcheck disable=SC2086
  "$ropsim" run --fidelity functional $1 --method "$2" --compressibility \
    --hw-set "compression.depth_encoder=$3" --report "$work/r.json" --quiet >/dev/null
  /usr/bin/python3 -c '
import json, sys
b = [x for x in json.load(open(sys.argv[1]))["compressibility"]["buffers"] if x["buffer"] == "depth"][0]
print(b["bytes_uncompressed"], b["bytes_compressed"])' "$work/r.json"
}
echo "| input | method | depth bytes uncompressed | plane | fit | plane / uncompressed | fit / uncompressed | plane / fit |"
echo "|---|---|---:|---:|---:|---:|---:|---:|"
row() {  # LABEL INPUT-ARGS METHOD
  read -r u p < <(depth_bytes "$2" "$3" plane)
  read -r _ f < <(depth_bytes "$2" "$3" fit)
  /usr/bin/python3 -c 'import sys; l, m, u, p, f = sys.argv[1:]; u, p, f = int(u), int(p), int(f)
print(f"| {l} | {m} | {u} | {p} | {f} | {p / u:.3f} | {f / u:.3f} | {p / f:.3f} |")' "$1" "$3" "$u" "$p" "$f"
}
for spp in 4 16 64; do
  for m in opaque lk; do row "cloth, $spp spp" "--scene cloth --spp $spp" "$m"; done
done
for m in opaque lk; do row "motor, 16 spp" "--trace $work/motor.rtr" "$m"; done
