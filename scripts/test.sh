#!/usr/bin/env bash
# Quick start 2/2: installs what is missing, builds, runs the whole test suite.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/scripts/build.sh"
bash "$root/scripts/ctest_cost.sh" seed "$root/build"
cd "$root/build"
ctest --output-on-failure -j "$(nproc)"
