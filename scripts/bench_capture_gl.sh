#!/usr/bin/env bash
# GL capture cost against llvmpipe's own: `ropsim capture gl` of one recorded
# glmark2 jellyfish frame (default 1920x1080, frame 10, 16 spp) side by side
# with llvmpipe rendering the passes that capture needs, in one run on the
# same recording (made once with apitrace under Xvfb, or given as TRACE).
# Each of N runs (default 3) times three replays of the recording to the frame:
#   capture  the whole capture (passes with record appends, read-back, API-order
#            sort, zstd trace write)
#   passes   ROPSIM_GL_RENDER_PASSES=1 with --list: each of the frame's draws
#            re-executed once per pass (17 at 16 spp) with the application's
#            own program and state into a colour buffer of the target's size,
#            glFinish, no records, no read-back
#   list     --list alone: the replay to the frame, no passes
# and prints capture - list and passes - list (the frame's passes only), their
# ratio against the bound (capture <= 3 x passes), the absolute capture time,
# peak memory, and the library's own phase times (ROPSIM_GL_TIMES). The best
# (smallest) of the N runs counts; the machine is shared, so runs vary.
# usage: scripts/bench_capture_gl.sh [RUNS] [TRACE] [FRAME] [SPP]
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
runs="${1:-3}"
trace="${2:-}"
frame="${3:-10}"
spp="${4:-16}"
ropsim="$root/build/ropsim"
[ -x "$ropsim" ] && [ -f "$root/build/libropsim_glcapture.so" ] || bash "$root/scripts/build.sh" >/dev/null
tmp="$(mktemp -d)"
xvfb_pid=""
trap '[ -n "$xvfb_pid" ] && kill "$xvfb_pid" 2>/dev/null; rm -rf "$tmp"' EXIT
if [ -z "$trace" ]; then
  trace="$tmp/jellyfish.trace"
  display=":$((90 + RANDOM % 400))"
  Xvfb "$display" -screen 0 1920x1080x24 >"$tmp/xvfb.log" 2>&1 &
  xvfb_pid=$!
  sleep 2
  DISPLAY="$display" apitrace trace -o "$trace" glmark2 --size 1920x1080 -b jellyfish:duration=3 >"$tmp/record.log" 2>&1
  kill "$xvfb_pid"
  wait "$xvfb_pid" 2>/dev/null || true
  xvfb_pid=""
fi
capture=(capture gl --apitrace "$trace" --frame "$frame" --spp "$spp" --width 1920 --height 1080 --quiet)
now() { date +%s.%N; }
best() { sort -g | head -1; }
for i in $(seq "$runs"); do
  t0=$(now)
  ROPSIM_GL_TIMES="$tmp/times.json" /usr/bin/time -f %M -o "$tmp/rss" "$ropsim" "${capture[@]}" -o "$tmp/t.trace" \
    >/dev/null
  t1=$(now)
  ROPSIM_GL_RENDER_PASSES=1 "$ropsim" "${capture[@]}" --list >/dev/null
  t2=$(now)
  "$ropsim" "${capture[@]}" --list >/dev/null
  t3=$(now)
  python3 - "$t0" "$t1" "$t2" "$t3" "$(cat "$tmp/rss")" "$tmp/times.json" "$i" "$(stat -c %s "$tmp/t.trace")" \
    >>"$tmp/runs" <<'EOF'
import json, sys
t0, t1, t2, t3 = map(float, sys.argv[1:5])
cap, passes, lst = t1 - t0, t2 - t1, t3 - t2
ph = json.load(open(sys.argv[6]))
phases = ", ".join(f"{k} {ph[k]:.2f}" for k in ("passes", "read_back", "decode", "build", "write"))
print(f"{cap - lst:.3f} {passes - lst:.3f} {cap:.3f} {lst:.3f} {int(sys.argv[5]) / 1e6:.2f} {sys.argv[8]} {phases}")
EOF
  read -r c p a l m b ph <<<"$(tail -1 "$tmp/runs")"
  echo "run $i: capture $a s, passes-only replay $(python3 -c "print(f'{$p + $l:.3f}')") s, list replay $l s;" \
    "frame: capture $c s, passes $p s; peak $m GB, trace $b bytes; library phases (s): $ph"
done
read -r c p a l m b ph <<<"$(sort -g "$tmp/runs" | head -1)"
pbest=$(cut -d' ' -f2 "$tmp/runs" | best)
python3 - "$c" "$pbest" "$a" "$m" <<'EOF'
import sys
c, p, a, m = map(float, sys.argv[1:5])
r = c / p
print(f"best of runs: capture of the frame {c:.2f} s (whole command {a:.2f} s, peak {m:.2f} GB); "
      f"llvmpipe rendering its passes {p:.2f} s; ratio {r:.1f} x (bound <= 3 x: {'met' if r <= 3 else 'NOT met'})")
EOF
