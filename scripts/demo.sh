#!/usr/bin/env bash
# Quick start 1/2: installs what is missing, builds Release, runs the default
# scene (cloth, 16 spp) with the main methods and writes images and reports
# under out/demo/; then the smoke study (out/study/smoke, report/index.html).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# Only what the demo runs: the CLI (and the image codec module it loads);
# scripts/test.sh builds the rest (tests, benchmarks, RTL models).
bash "$root/scripts/build.sh" --target ropsim
ropsim="$root/build/ropsim"
out="$root/out/demo"
mkdir -p "$out"
scene=cloth
spp=16
"$ropsim" scene "$scene" --spp "$spp" -o "$out/$scene-${spp}spp.trace"
"$ropsim" trace info "$out/$scene-${spp}spp.trace"
for m in reference lk enderton naive a2c; do
  "$ropsim" run --trace "$out/$scene-${spp}spp.trace" --method "$m" --vs-reference \
    --out "$out/$scene-$m.png" --out "$out/$scene-$m.exr" --report "$out/$scene-$m.json" --quiet
done
# The same trace through the cycle-approximate SystemC pipeline (default design):
# the image is the golden one; the report adds cycles, bandwidth and stalls.
"$ropsim" run --fidelity cycle --hw "$root/configs/default.toml" --trace "$out/$scene-${spp}spp.trace" --method lk \
  --out "$out/$scene-lk-cycle.png" --report "$out/$scene-lk-cycle.json"
echo
echo "RMSE against the A-buffer reference ($scene, $spp spp, 8-bit units):"
for m in lk enderton naive a2c; do
  printf '  %-9s %s\n' "$m" "$("$ropsim" compare "$out/$scene-$m.exr" "$out/$scene-reference.exr")"
done
/usr/bin/python3 "$root/analysis/contact_sheet.py" "$out/$scene-contact.png" \
  "$out/$scene-reference.png" "$out/$scene-lk.png" "$out/$scene-enderton.png" "$out/$scene-naive.png" "$out/$scene-a2c.png"
echo
echo "wrote under $out:"
ls -1 "$out" | sed 's/^/  /'
# A what-if study: every method x 2 spp x both fidelities x 2 ROP-unit counts on
# two scenes, on every core, into a database, with its HTML report.
echo
# --force: the folder is the demo's own; a rebuilt ropsim makes other points (their hashes
# hold the version), which a plain run into the same folder refuses.
"$ropsim" study run "$root/studies/smoke.toml" --out "$root/out/study/smoke" --force --quiet
"$ropsim" study report "$root/out/study/smoke"
