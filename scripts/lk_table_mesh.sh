#!/usr/bin/env bash
# LK 2011 Table 1 on a captured mesh scene: captures SCENE.toml at 4..64 spp
# (ropsim capture), replays each trace with lk and enderton against the
# A-buffer reference (ropsim run --vs-reference), prints a Markdown table of
# RMSE (8-bit units) and the ratio lk/enderton beside the paper's.
# usage: scripts/lk_table_mesh.sh SCENE.toml [WIDTH HEIGHT] [SEED]
#   e.g. scripts/lk_table_mesh.sh traces/scenes/mesh/motor.toml 960 540
# Memory: the reference holds every fragment (~1 KB each at 64 spp).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
scene="${1:?usage: lk_table_mesh.sh SCENE.toml [WIDTH HEIGHT] [SEED]}"
size=()
[ $# -ge 3 ] && size=(--width "$2" --height "$3")
seed="${4:-1}"
ropsim="$root/build/ropsim"
[ -x "$ropsim" ] || bash "$root/scripts/build.sh" >/dev/null
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
rmse() { /usr/bin/python3 -c "import json,sys; print('%.2f' % json.load(open(sys.argv[1]))['vs_reference']['rmse_8bit'])" "$1"; }
declare -A paper=([motor:4]=0.81 [motor:8]=0.71 [motor:16]=0.60 [motor:32]=0.52 [motor:64]=0.46
                  [cloth:4]=0.88 [cloth:8]=0.79 [cloth:16]=0.67 [cloth:32]=0.57 [cloth:64]=0.49)
kind=motor
case "$(basename "$scene")" in cloth*) kind=cloth ;; esac
echo "| spp | fragments | lk | enderton | ratio lk/enderton | LK 2011 ${kind^^} ratio |"
echo "|---:|---:|---:|---:|---:|---:|"
for spp in 4 8 16 32 64; do
  "$ropsim" capture "$scene" --spp "$spp" "${size[@]}" --quiet -o "$tmp/t.trace"
  frags=$("$ropsim" trace validate "$tmp/t.trace" | awk '{print $3}')
  for m in lk enderton; do
    "$ropsim" run --trace "$tmp/t.trace" --method "$m" --seed "$seed" --vs-reference --report "$tmp/$m.json" --quiet
  done
  a=$(rmse "$tmp/lk.json"); b=$(rmse "$tmp/enderton.json")
  echo "| $spp | $frags | $a | $b | $(/usr/bin/python3 -c "print('%.2f' % ($a / $b))") | ${paper[$kind:$spp]} |"
done
