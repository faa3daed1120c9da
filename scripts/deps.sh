#!/usr/bin/env bash
# Installs the Debian packages ropsim needs, if any is missing. Sourced by
# demo.sh and test.sh; safe to run again (installs nothing when all are there).
set -euo pipefail
ROPSIM_PACKAGES=(
  cmake g++ make pkg-config
  libsystemc-dev libgtest-dev libbenchmark-dev libfmt-dev libopenimageio-dev
  libcli11-dev nlohmann-json3-dev libzstd-dev libxxhash-dev libtbb-dev
  libtomlplusplus-dev libassimp-dev libosmesa6-dev libsqlite3-dev sqlite3
  clang-format python3-numpy python3-matplotlib python3-pandas
  chromium
  verilator yosys iverilog
  gtkwave xvfb xauth
  glmark2-x11 apitrace mesa-utils libgl1-mesa-dri libgl-dev libglx-dev libegl-dev libx11-dev
)
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
