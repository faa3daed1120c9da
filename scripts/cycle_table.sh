#!/usr/bin/env bash
# Cycle-model figures for docs/results.md: one scene through every committed
# config, and a ROP-count sweep with unlimited memory. Usage:
#   scripts/cycle_table.sh [SCENE] [SPP] [METHOD]      (default: cloth 16 lk)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/scripts/build.sh" >/dev/null
ropsim="$root/build/ropsim"
scene="${1:-cloth}"; spp="${2:-16}"; method="${3:-lk}"
tmp="$(mktemp -d)"; trap 'rm -rf "$tmp"' EXIT
field() { /usr/bin/python3 -c "import json,sys; t=json.load(open('$1'))['timing']; print($2)"; }
echo "| config | cycles | frame time (us) | fragments/clock | DRAM read+written (MB) | GB/s achieved / peak | bottleneck |"
echo "|---|---:|---:|---:|---:|---:|---|"
for c in "$root"/configs/*.toml; do
  "$ropsim" run --fidelity cycle --hw "$c" --scene "$scene" --spp "$spp" --method "$method" --quiet --report "$tmp/r.json"
  field "$tmp/r.json" "'| $(basename "$c" .toml) | %d | %.1f | %.3f | %.1f | %.1f / %.0f | %s |' % (t['total_cycles'], t['frame_time_us'], t['fragments_per_clock'], (t['dram']['bytes_read']+t['dram']['bytes_written'])/1e6, t['dram']['achieved_gbps'], t['dram']['peak_gbps'], t['bottleneck'])"
done
echo
echo "ROP-count sweep, unlimited memory, source 4 fragments/clock, 8-pixel tiles, 256-entry ROP FIFOs:"
echo "| ROPs | fragments/clock | bottleneck |"
echo "|---:|---:|---|"
for n in 1 2 4 8 16; do
  "$ropsim" run --fidelity cycle --scene "$scene" --spp "$spp" --method "$method" --quiet --report "$tmp/r.json" \
    --hw-set dram.channels=64 --hw-set dram.bytes_per_clock=4096 --hw-set dram.latency_cycles=0 \
    --hw-set dram.row_miss_cycles=0 --hw-set cache.size_bytes=1048576 --hw-set distributor.rop_units=$n \
    --hw-set distributor.tile_pixels=8 --hw-set distributor.fifo_depth=256 --hw-set ordering.window=16
  field "$tmp/r.json" "'| $n | %.3f | %s |' % (t['fragments_per_clock'], t['bottleneck'])"
done
