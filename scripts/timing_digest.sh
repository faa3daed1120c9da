#!/usr/bin/env bash
# Prints one line per cycle-model run -- config, method, trace, total cycles and
# a digest of every timing figure in the report (host figures and the
# bottleneck's classification aside) -- over
# configs/*.toml x {lk, opaque, enderton, naive, a2c, blend} x {cloth 16 spp, cloth 4
# spp, eight-layers 16 spp}. A refactor that must not change the model leaves
# this output unchanged: the ctest TimingDigest.MatchesTheCommittedDigest
# compares it with tests/data/timing_digest.expected. Extra args go to every
# `ropsim run` (e.g. --lockstep, which must print the same lines).
# ROPSIM=path/to/ropsim uses that binary instead of building build/ropsim.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if [ -z "${ROPSIM:-}" ]; then
  bash "$root/scripts/build.sh" >/dev/null
  ROPSIM="$root/build/ropsim"
fi
b="$ROPSIM"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
"$b" scene cloth --spp 16 -o "$tmp/cloth16.rtr" >/dev/null
"$b" scene cloth --spp 4 -o "$tmp/cloth4.rtr" >/dev/null
"$b" scene eight-layers --spp 16 -o "$tmp/layers16.rtr" >/dev/null
for cfg in "$root"/configs/*.toml; do
  for m in lk opaque enderton naive a2c blend; do
    for tr in cloth16 cloth4 layers16; do
      "$b" run --fidelity cycle --hw "$cfg" --trace "$tmp/$tr.rtr" --method "$m" --quiet \
        --out "$tmp/o.png" --report "$tmp/r.json" "$@"
      /usr/bin/python3 - "$tmp/r.json" "$(basename "$cfg" .toml) $m $tr" <<'PY'
import hashlib, json, sys
t = json.load(open(sys.argv[1]))["timing"]
t.pop("host", None)
# The bottleneck is classified from these figures (docs/reports.md "The
# bottleneck"): reporting, not timing.
for k in ("bottleneck", "bottleneck_kind", "bottleneck_bounds", "memory_bound"):
    t.pop(k, None)
for u in t["units"]:
    u.pop("activations", None)
print(sys.argv[2], t["total_cycles"], hashlib.sha256(json.dumps(t, sort_keys=True).encode()).hexdigest()[:16])
PY
    done
  done
done
# The other methods: the default design, two traces.
for m in hashed hashed-a2c slab wboit lk+ac lk+depth lk+depth+ac enderton+ac enderton+depth enderton+depth+ac; do
  for tr in cloth4 layers16; do
    "$b" run --fidelity cycle --hw "$root/configs/default.toml" --trace "$tmp/$tr.rtr" --method "$m" --quiet \
      --out "$tmp/o.png" --report "$tmp/r.json" "$@"
    /usr/bin/python3 - "$tmp/r.json" "default $m $tr" <<'PY'
import hashlib, json, sys
t = json.load(open(sys.argv[1]))["timing"]
t.pop("host", None)
# The bottleneck is classified from these figures (docs/reports.md "The
# bottleneck"): reporting, not timing.
for k in ("bottleneck", "bottleneck_kind", "bottleneck_bounds", "memory_bound"):
    t.pop(k, None)
for u in t["units"]:
    u.pop("activations", None)
for p in t.get("passes", []):
    p.pop("host", None)
print(sys.argv[2], t["total_cycles"], hashlib.sha256(json.dumps(t, sort_keys=True).encode()).hexdigest()[:16])
PY
  done
done
