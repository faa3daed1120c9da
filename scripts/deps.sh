#!/usr/bin/env bash
# Installs the Debian packages ropsim needs, if any is missing. Sourced by
# demo.sh and test.sh; safe to run again (installs nothing when all are there).
# Run as `scripts/deps.sh --apps`, it also installs the applications of the
# suite of application frames (traces/apps/*.toml `package`), some of them
# large game packages that CI never installs.
set -euo pipefail
ROPSIM_PACKAGES=(
  cmake g++ make pkg-config
  libsystemc-dev libgtest-dev libbenchmark-dev libfmt-dev libopenimageio-dev libpng-dev
  libcli11-dev nlohmann-json3-dev libzstd-dev libxxhash-dev libtbb-dev
  libtomlplusplus-dev libassimp-dev libosmesa6-dev libsqlite3-dev sqlite3
  clang-format python3-numpy python3-matplotlib python3-pandas
  chromium
  verilator yosys iverilog
  gtkwave xvfb xauth
  glmark2-x11 apitrace mesa-utils libgl1-mesa-dri libgl-dev libglx-dev libegl-dev libx11-dev
)
if [ "${BASH_SOURCE[0]}" = "$0" ] && [ "${1:-}" = "--apps" ]; then
  apps_dir="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/traces/apps"
  while read -r p; do ROPSIM_PACKAGES+=("$p"); done < <(sed -n 's/^package *= *"\([^"]*\)".*/\1/p' "$apps_dir"/*.toml | sort -u)
fi
missing=()
for p in "${ROPSIM_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "ropsim: installing ${missing[*]}"
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -q
  $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi
