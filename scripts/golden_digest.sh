#!/usr/bin/env bash
# Prints one line per golden-model run -- scene, method, spp, a digest of the
# counters, of the PNG and the RMSE against the A-buffer reference (17
# significant digits) -- over {cloth, eight-layers, smoke} x every method x
# {4, 16} spp. The golden model's outputs must not change in a refactor: the
# ctest GoldenDigest.MatchesTheCommittedDigest compares this with
# tests/data/golden_digest.expected. (The bit-exact matrix compares the
# fidelities with each other; this compares the golden model with its past.)
# ROPSIM=path/to/ropsim uses that binary instead of building build/ropsim.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if [ -z "${ROPSIM:-}" ]; then
  bash "$root/scripts/build.sh" >/dev/null
  ROPSIM="$root/build/ropsim"
fi
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
for scene in cloth eight-layers smoke; do
  for m in lk enderton naive a2c opaque reference hashed hashed-a2c slab wboit lk+ac lk+depth lk+depth+ac \
    enderton+ac enderton+depth enderton+depth+ac blend; do
    for spp in 4 16; do
      "$ROPSIM" run --scene "$scene" --spp "$spp" --method "$m" --vs-reference --quiet \
        --out "$tmp/o.png" --report "$tmp/r.json"
      /usr/bin/python3 - "$tmp/r.json" "$tmp/o.png" "$scene $m $spp" <<'PY'
import hashlib, json, sys
r = json.load(open(sys.argv[1]))
c = hashlib.sha256(json.dumps(r["counters"], sort_keys=True).encode()).hexdigest()[:16]
p = hashlib.sha256(open(sys.argv[2], "rb").read()).hexdigest()[:16]
print(sys.argv[3], c, p, "%.17g" % r["vs_reference"]["rmse_8bit"])
PY
    done
  done
done
