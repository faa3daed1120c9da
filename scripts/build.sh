#!/usr/bin/env bash
# Configures and builds ropsim (Release) in build/.
#   scripts/build.sh                      every target (the CLI, tests, benchmarks, RTL models)
#   scripts/build.sh --target ropsim      only the named targets (repeatable; what the demo runs)
# Other arguments go to cmake's configure step (e.g. -DROPSIM_WERROR=ON).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
targets=()
configure=()
while [ $# -gt 0 ]; do
  case "$1" in
    --target) [ $# -ge 2 ] || { echo "scripts/build.sh: --target needs a target name" >&2; exit 1; }
              targets+=(--target "$2"); shift 2 ;;
    *) configure+=("$1"); shift ;;
  esac
done
bash "$root/scripts/deps.sh"
cmake -S "$root" -B "$root/build" -DCMAKE_BUILD_TYPE=Release ${configure[@]+"${configure[@]}"} >/dev/null
cmake --build "$root/build" -j "$(nproc)" ${targets[@]+"${targets[@]}"}
