#!/usr/bin/env bash
# Study host-speed benchmark (not a test): a 16-point study of cloth at 16 spp
# in the cycle fidelity (lk and enderton x 4 ROP-unit counts x 2 seeds, no
# reference) run with -j 1 and -j 2, beside the same 16 runs as bare
# `ropsim run` calls one after another, all in one run, ROUNDS times (default 3).
# Prints each wall time (min / median / max) and the two ratios the study
# executor is held to: -j 1 / -j 2 (target >= 1.8 on 2 cores) and
# -j 1 / bare runs (target <= 1.10).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
rounds="${1:-3}"
bash "$root/scripts/build.sh" >/dev/null
b="$root/build/ropsim"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
cat >"$tmp/bench.toml" <<'TOML'
[study]
name = "bench"
reference = false

[inputs]
scenes = ["cloth"]

[axes]
fidelity = "cycle"
method = ["lk", "enderton"]
"distributor.rop_units" = [1, 2, 4, 8]
seed = [1, 2]
spp = 16
TOML
now() { date +%s.%N; }
: >"$tmp/times"
for ((r = 0; r < rounds; ++r)); do
  for j in 1 2; do
    rm -rf "$tmp/s$j"
    t0=$(now)
    "$b" study run "$tmp/bench.toml" --out "$tmp/s$j" -j "$j" --quiet
    echo "j$j $t0 $(now)" >>"$tmp/times"
  done
  t0=$(now)
  for m in lk enderton; do
    for u in 1 2 4 8; do
      for seed in 1 2; do
        "$b" run --scene cloth --spp 16 --fidelity cycle --method "$m" --seed "$seed" \
          --hw-set "distributor.rop_units=$u" --quiet --out "$tmp/o.png" --report "$tmp/o.json"
      done
    done
  done
  echo "bare $t0 $(now)" >>"$tmp/times"
done
/usr/bin/python3 - "$tmp/times" <<'PY'
import statistics, sys
t = {}
for line in open(sys.argv[1]):
    k, a, b = line.split()
    t.setdefault(k, []).append(float(b) - float(a))
for k in ("j1", "j2", "bare"):
    v = t[k]
    print(f"{k:5} wall s: min {min(v):.2f}  median {statistics.median(v):.2f}  max {max(v):.2f}")
m = {k: statistics.median(v) for k, v in t.items()}
print(f"speed-up -j 2 over -j 1: {m['j1'] / m['j2']:.2f}x (target >= 1.8)")
print(f"-j 1 over the bare runs: {m['j1'] / m['bare']:.3f} (target <= 1.10)")
PY
