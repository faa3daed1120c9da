#!/usr/bin/env bash
# Memory benchmark (not a test; docs/testing.md "Memory"): the fuzz regression
# trace whose header says 32768 x 32768 (576 fragments in 64 pixels) run in
# each fidelity, with the A-buffer reference, and writing the 1-gigapixel
# image as EXR and as PNG. Prints each run's peak resident memory (ropsim's own
# VmHWM, host.peak_rss_bytes), the state charged against --memory-limit, the
# wall time and the output's size.
#   scripts/bench_memory.sh [BUILD_DIR]
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
b="${1:-$root/build}"
[ -x "$b/ropsim" ] || bash "$root/scripts/build.sh" >/dev/null
trace="$root/fuzz/regressions/trace/screen-32768-squared.rtrace"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
printf '| run | peak RSS (MiB) | charged peak (MiB) | wall (s) | output (bytes) |\n|---|---:|---:|---:|---:|\n'
run() {
  local name="$1"
  shift
  local t0 t1 size="-"
  t0=$(date +%s.%N)
  "$b/ropsim" run --trace "$trace" --report "$out/r.json" --quiet "$@"
  t1=$(date +%s.%N)
  for f in "$out"/img.*; do [ -f "$f" ] && size=$(stat -c %s "$f") && rm -f "$f"; done
  /usr/bin/python3 - "$out/r.json" "$name" "$t0" "$t1" "$size" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))["host"]
print(f"| {sys.argv[2]} | {r['peak_rss_bytes'] / 2**20:.1f} | {r['memory_charged_peak_bytes'] / 2**20:.2f} | "
      f"{float(sys.argv[4]) - float(sys.argv[3]):.1f} | {sys.argv[5]} |")
PY
}
run "functional, report" --fidelity functional
run "cycle, report" --fidelity cycle
run "functional, --vs-reference" --vs-reference
run "functional, EXR" --out "$out/img.exr"
run "functional, PNG" --out "$out/img.png"
