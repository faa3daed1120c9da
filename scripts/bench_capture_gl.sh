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
# and prints capture - list and passes - list (the frame's passes only; the
# library also times the passes alone, from the first draw to glFinish), their
# ratio against the bound (capture <= 3 x passes), the absolute capture time,
# peak memory, and the capture's phase times (ROPSIM_GL_TIMES). The medians
# of the N runs count; a difference of two replays varies by some 0.3 s.
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
for i in $(seq "$runs"); do
  t0=$(now)
  ROPSIM_GL_TIMES="$tmp/capture.json" /usr/bin/time -f %M -o "$tmp/rss" "$ropsim" "${capture[@]}" \
    -o "$tmp/t.trace" >/dev/null
  t1=$(now)
  ROPSIM_GL_RENDER_PASSES=1 ROPSIM_GL_TIMES="$tmp/passes.json" "$ropsim" "${capture[@]}" --list >/dev/null
  t2=$(now)
  "$ropsim" "${capture[@]}" --list >/dev/null
  t3=$(now)
  python3 - "$t0" "$t1" "$t2" "$t3" "$(cat "$tmp/rss")" "$tmp" "$i" "$(stat -c %s "$tmp/t.trace")" <<'EOF'
import json, sys
t0, t1, t2, t3 = map(float, sys.argv[1:5])
tmp, run = sys.argv[6], sys.argv[7]
cap, passes, lst = t1 - t0, t2 - t1, t3 - t2
ph = json.load(open(f"{tmp}/capture.json"))
lib_passes = json.load(open(f"{tmp}/passes.json"))["passes"]
with open(f"{tmp}/runs.json", "a") as f:
    f.write(json.dumps({"cap": cap - lst, "passes": passes - lst, "lib_passes": lib_passes, "whole": cap,
                        "rss": int(sys.argv[5]) / 1e6, "phases": ph}) + "\n")
phases = ", ".join(f"{k} {ph[k]:.2f}" for k in ("passes", "read_back", "build", "write"))
print(f"run {run}: replays: capture {cap:.2f} s, passes {passes:.2f} s, list {lst:.2f} s; frame: capture "
      f"{cap - lst:.2f} s, passes {passes - lst:.2f} s (library's timer {lib_passes:.2f} s); peak "
      f"{int(sys.argv[5]) / 1e6:.2f} GB, trace {int(sys.argv[8]) / 1e6:.1f} MB; capture phases (s): {phases}")
EOF
done
python3 - "$tmp/runs.json" <<'EOF'
import json, statistics, sys
runs = [json.loads(l) for l in open(sys.argv[1])]
med = lambda k: statistics.median(r[k] for r in runs)
c, p, lp, a, m = med("cap"), med("passes"), med("lib_passes"), med("whole"), max(r["rss"] for r in runs)
print(f"median of {len(runs)} runs: capture of the frame {c:.2f} s (whole command {a:.2f} s, peak {m:.2f} GB); "
      f"llvmpipe rendering its passes {p:.2f} s (library's timer {lp:.2f} s)")
r = max(c / p, c / lp)
print(f"ratio {c / p:.1f} x ({c / lp:.1f} x against the library's timer); bound capture <= 3 x passes: "
      f"{'met' if r <= 3 else 'NOT met'}")
EOF
