#!/usr/bin/env bash
# Synthesis cost of the reference RTL (docs/rtl.md "Synthesis"): each module
# of rtl_models/rtl for a set of parameters, through Yosys's generic flow
# (synth -flatten; every flip-flop legalised to a plain D flip-flop, resets
# become logic; abc -g cmos2 maps the logic to NAND2, NOR2 and inverters),
# then per run:
#   cells        mapped cells (gates + flip-flops)
#   flipflops    D flip-flops
#   transistors  Yosys `stat -tech cmos`: NOT 2, NAND2/NOR2 4, DFF 16
#   nand2_eq     transistors / 4 (a NAND2 is 4 transistors)
#   levels       `ltp -noff`: longest path in gates between flip-flops,
#                inputs and outputs, i.e. the logic depth of the deepest stage
# Every run fails loudly on a latch or a cell the flow did not map.
#   scripts/synth.sh [--set small|sweep] [--match REGEX] [--out CSV] [--jobs N] [--yosys PATH]
# --set small is the CI check (one small parameter set per module); sweep is
# the range of docs/results.md (spp 1-64, hash bits 8-32, lanes 1-16, and the
# widths and stage counts the cost model of rtl_models/cost is checked on);
# docs/data/rtl_synth_sweep.csv holds its rows.
# --match keeps the runs whose line ("TOP NAME=VALUE ...") matches REGEX.
# --set latch synthesises tests/rtl/rop_latch_selftest.sv, which holds a
# latch: it must fail (RTL.synth_latch_check shows the check can fail).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
set_name=small
match=""
out=""
jobs=1
yosys=yosys
while [ $# -gt 0 ]; do
  case "$1" in
    --set) set_name="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --match) match="$2"; shift 2 ;;
    --jobs) jobs="$2"; shift 2 ;;
    --yosys) yosys="$2"; shift 2 ;;
    *) echo "synth.sh: unknown argument $1" >&2; exit 1 ;;
  esac
done
[ -n "$out" ] || out="$root/build/synth_${set_name}.csv"

# One run per line: TOP NAME=VALUE...
runs() {
  if [ "$set_name" = small ]; then
    echo "rop_alpha_ref LANES=1 STAGES=4 HASH_BITS=8 SPP=16 SID_BITS=8 PIXEL_BITS=16"
    echo "rop_opacity_test LANES=4 ALPHA_BITS=8 HASH_BITS=8 STAGES=1"
    echo "rop_tracker_update SPP=4 SID_BITS=4 STAGES=1"
    echo "rop_depth_compare LANES=4 STAGES=2"
    echo "rop_hilbert_index ORDER=4 STAGES=1"
    echo "rop_bitonic_sorter N=4"
  elif [ "$set_name" = latch ]; then
    echo "rop_latch_selftest WIDTH=4"
  elif [ "$set_name" = sweep ]; then
    for h in 8 16 24 32; do
      for l in 1 4 16; do echo "rop_alpha_ref LANES=$l STAGES=4 HASH_BITS=$h SPP=16 SID_BITS=32 PIXEL_BITS=32"; done
      echo "rop_alpha_ref LANES=1 STAGES=1 HASH_BITS=$h SPP=16 SID_BITS=32 PIXEL_BITS=32"
      for s in 4 16 64; do echo "rop_opacity_test LANES=$s ALPHA_BITS=32 HASH_BITS=$h STAGES=1"; done
    done
    for l in 2 8; do echo "rop_alpha_ref LANES=$l STAGES=4 HASH_BITS=32 SPP=16 SID_BITS=32 PIXEL_BITS=32"; done
    for s in 4 8 16 32 64; do
      echo "rop_tracker_update SPP=$s SID_BITS=32 STAGES=1"
      echo "rop_depth_compare LANES=$s STAGES=2"
      echo "rop_bitonic_sorter N=$s"
    done
    for o in 8 12 16; do echo "rop_hilbert_index ORDER=$o STAGES=1"; done
    # The other widths and stage counts a design sets (the cost model of
    # rtl_models/cost: surface-id and alpha widths, pipeline stages, hash
    # widths between the ones above).
    for st in 2 3 5 8; do echo "rop_alpha_ref LANES=1 STAGES=$st HASH_BITS=16 SPP=16 SID_BITS=32 PIXEL_BITS=32"; done
    for h in 16 32; do echo "rop_alpha_ref LANES=1 STAGES=4 HASH_BITS=$h SPP=16 SID_BITS=4 PIXEL_BITS=32"; done
    for h in 12 20; do echo "rop_alpha_ref LANES=1 STAGES=4 HASH_BITS=$h SPP=16 SID_BITS=32 PIXEL_BITS=32"; done
    for a in 4 8 16; do
      for h in 8 16 32; do echo "rop_opacity_test LANES=16 ALPHA_BITS=$a HASH_BITS=$h STAGES=1"; done
    done
    echo "rop_opacity_test LANES=16 ALPHA_BITS=32 HASH_BITS=16 STAGES=2"
    for b in 1 4 8 16; do echo "rop_tracker_update SPP=16 SID_BITS=$b STAGES=1"; done
    echo "rop_tracker_update SPP=16 SID_BITS=32 STAGES=3"
    for st in 1 4; do echo "rop_depth_compare LANES=16 STAGES=$st"; done
    for s in 1 2; do
      echo "rop_tracker_update SPP=$s SID_BITS=32 STAGES=1"
      echo "rop_bitonic_sorter N=$s"
    done
  else
    echo "synth.sh: unknown set $set_name (small, sweep or latch)" >&2
    exit 1
  fi
}

tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

# synth_one INDEX TOP PARAMS...: writes $tmp/INDEX.csv (one row) or fails.
synth_one() {
  local i="$1" top="$2"
  shift 2
  local chparam="" params="" start end
  for p in "$@"; do
    chparam+=" -chparam ${p%%=*} ${p#*=}"
    params+="${params:+ }$p"
  done
  local src="$root/rtl_models/rtl/$top.sv"
  [ -f "$src" ] || src="$root/tests/rtl/$top.sv"
  start=$(date +%s.%N)
  local rc=0
  "$yosys" -l "$tmp/$i.log" -q -p "
      read_verilog -sv $root/rtl_models/rtl/rop_delay.sv $src
      hierarchy -top $top $chparam
      synth -flatten -top $top
      dfflegalize -cell \$_DFF_P_ x
      abc -g cmos2
      opt_clean
      tee -q -o $tmp/$i.stat stat -tech cmos
      tee -q -o $tmp/$i.ltp ltp -noff" >/dev/null 2>&1 || rc=$?
  end=$(date +%s.%N)
  # A latch first: the flip-flop legalisation then stops on it.
  if grep -q "^Latch inferred" "$tmp/$i.log" || grep -qsi "DLATCH" "$tmp/$i.stat"; then
    echo "FAIL: $top $params: Yosys reports a latch ($(grep -m1 "^Latch inferred" "$tmp/$i.log" | cut -c1-100))" >&2
    return 1
  fi
  if [ "$rc" -ne 0 ]; then
    echo "FAIL: $top $params: yosys failed (log: $(tail -3 "$tmp/$i.log"))" >&2
    return 1
  fi
  # Every cell must be a mapped gate or a D flip-flop.
  local bad
  bad="$(awk '$1 ~ /^\$/ && $1 !~ /^\$_(NAND|NOR|NOT|DFF_P)_$/ {print $1}' "$tmp/$i.stat" | tr '\n' ' ')"
  if [ -n "$bad" ]; then
    echo "FAIL: $top $params: unmapped cells: $bad" >&2
    return 1
  fi
  if grep -qi "unknown\|no transistor" "$tmp/$i.stat"; then
    echo "FAIL: $top $params: stat -tech cmos has no transistor count for a cell" >&2
    return 1
  fi
  local cells ffs tr levels
  cells="$(awk '/Number of cells:/ {print $4}' "$tmp/$i.stat" | tail -1)"
  ffs="$(awk '$1 == "$_DFF_P_" {print $2}' "$tmp/$i.stat" | tail -1)"
  tr="$(awk '/Estimated number of transistors:/ {print $5}' "$tmp/$i.stat" | tail -1)"
  levels="$(sed -n 's/.*(length=\([0-9]*\)).*/\1/p' "$tmp/$i.ltp" | tail -1)"
  echo "$top,\"$params\",${cells:-0},${ffs:-0},${tr:-0},$(( ${tr:-0} / 4 )),${levels:-0},$(echo "$end - $start" | bc)" > "$tmp/$i.csv"
  echo "$top $params: ${cells:-0} cells, ${ffs:-0} flip-flops, ${tr:-0} transistors, ${levels:-0} levels"
}
export -f synth_one
export root yosys tmp

t0=$(date +%s)
runs | { if [ -n "$match" ]; then grep -E -- "$match" || true; else cat; fi; } | awk '{print NR, $0}' | xargs -P "$jobs" -L 1 bash -c 'synth_one "$@"' _
{
  echo "module,params,cells,flipflops,transistors,nand2_eq,levels,seconds"
  for f in $(ls "$tmp"/*.csv | sort -V); do cat "$f"; done
} > "$out.tmp"
mv "$out.tmp" "$out"
echo "wrote $out: $(($(wc -l < "$out") - 1)) runs in $(($(date +%s) - t0)) s"
