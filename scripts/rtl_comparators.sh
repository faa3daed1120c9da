#!/usr/bin/env bash
# The bitonic sorter's compare-exchange elements, counted in the elaborated
# netlist (Yosys: one $gt cell per element, rtl_models/rtl/
# rop_bitonic_sorter.sv), against Batcher's n log2(n) (log2(n) + 1) / 4 for
# n = 4 .. 64. Fails naming the width that differs.
#   scripts/rtl_comparators.sh [YOSYS]
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
yosys="${1:-yosys}"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
for n in 4 8 16 32 64; do
  k=0
  while [ $((1 << k)) -lt "$n" ]; do k=$((k + 1)); done
  want=$((n * k * (k + 1) / 4))
  "$yosys" -q -p "read_verilog -sv $root/rtl_models/rtl/rop_bitonic_sorter.sv;
    hierarchy -top rop_bitonic_sorter -chparam N $n; tee -q -o $tmp/count.txt select -count t:\$gt" >/dev/null
  got="$(grep -o '[0-9]*' "$tmp/count.txt" | head -1)"
  if [ "$got" != "$want" ]; then
    echo "FAIL: n = $n: $got compare-exchange elements in the netlist, n log2(n) (log2(n) + 1) / 4 = $want"
    exit 1
  fi
  echo "n = $n: $got compare-exchange elements = n log2(n) (log2(n) + 1) / 4"
done
