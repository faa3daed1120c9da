#!/usr/bin/env bash
# Host-speed benchmark (not a test) of the trace payload checksum
# (docs/trace-format.md section 2.3): the golden model (lk) reading cloth at
# 16 spp, 1024x1024 (1.63 M fragments) from a file, uncompressed and zstd, by
# a base ropsim reading the trace without checksum and by this tree's ropsim
# reading it with and without checksum. Alternating runs, ROUNDS times (default
# 7); per process: host.fragments_per_second of the report (wall) and the
# process's user+system CPU seconds. Prints medians and ratios to the base.
#   scripts/bench_checksum.sh BASE_ROPSIM [ROUNDS]
#   (scripts/bench_ab.sh 3ce9eda builds build-ab/3ce9eda6fc36; then
#    cmake --build build-ab/3ce9eda6fc36/build --target ropsim)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
base="${1:?usage: bench_checksum.sh BASE_ROPSIM [ROUNDS]}"
rounds="${2:-7}"
head="$root/build/ropsim"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
for c in none zstd; do
  "$head" scene cloth --spp 16 --width 1024 --height 1024 --compression "$c" -o "$out/$c-ck.trace" >/dev/null
  "$head" scene cloth --spp 16 --width 1024 --height 1024 --compression "$c" --no-checksum -o "$out/$c-plain.trace" >/dev/null
done
for ((i = 0; i < rounds; ++i)); do
  for c in none zstd; do
    for side in base:plain head:plain head:ck; do
      bin="$head"
      [ "${side%%:*}" = base ] && bin="$base"
      tag="$c-${side%%:*}-${side##*:}"
      TIMEFORMAT="%3U %3S"
      { time "$bin" run --trace "$out/$c-${side##*:}.trace" --method lk --report "$out/$tag-$i.json" --quiet; } \
        2>"$out/$tag-$i.cpu"
    done
  done
done
/usr/bin/python3 - "$out" "$rounds" <<'PY'
import json, statistics, sys, os
out, rounds = sys.argv[1], int(sys.argv[2])
print(f"golden model (lk) reading cloth 16 spp 1024x1024 from a file, {rounds} alternating rounds; medians")
print(f"{'trace':6} {'side':18} {'M frag/s (wall)':>16} {'ratio':>7} {'CPU s':>7} {'ratio':>7}")
for c in ("none", "zstd"):
    base = None
    for side in ("base-plain", "head-plain", "head-ck"):
        fps = [json.load(open(os.path.join(out, f"{c}-{side}-{i}.json")))["host"]["fragments_per_second"] / 1e6 for i in range(rounds)]
        cpu = [sum(map(float, open(os.path.join(out, f"{c}-{side}-{i}.cpu")).read().split()[:2])) for i in range(rounds)]
        m, t = statistics.median(fps), statistics.median(cpu)
        if base is None: base = (m, t)
        print(f"{c:6} {side:18} {m:16.3f} {m / base[0]:7.3f} {t:7.3f} {base[1] / t:7.3f}")
PY
