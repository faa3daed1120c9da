#!/usr/bin/env bash
# LK 2011 Table 1 on a built-in scene: RMSE (8-bit units) of lk and enderton
# against the A-buffer reference at 4..64 spp, as a Markdown table.
# usage: scripts/lk_table.sh [SCENE] [SEED]     (default: cloth 1)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
scene="${1:-cloth}"
seed="${2:-1}"
ropsim="$root/build/ropsim"
[ -x "$ropsim" ] || bash "$root/scripts/build.sh" >/dev/null
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
rmse() { /usr/bin/python3 -c "import json,sys; print('%.2f' % json.load(open(sys.argv[1]))['vs_reference']['rmse_8bit'])" "$1"; }
echo "| spp | lk | enderton | ratio lk/enderton |"
echo "|---:|---:|---:|---:|"
for spp in 4 8 16 32 64; do
  for m in lk enderton; do
    "$ropsim" run --scene "$scene" --spp "$spp" --method "$m" --seed "$seed" --vs-reference \
      --report "$tmp/$m.json" --quiet
  done
  a=$(rmse "$tmp/lk.json"); b=$(rmse "$tmp/enderton.json")
  echo "| $spp | $a | $b | $(/usr/bin/python3 -c "print('%.2f' % ($a / $b))") |"
done
