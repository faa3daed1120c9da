#!/usr/bin/env bash
# ctest starts the tests it knows to be longest first, from the times it
# keeps in BUILD/Testing/Temporary/CTestCostData.txt. A build folder that has
# none yet (a fresh checkout, CI) would start them in file order and could
# end on one long test with the other cores idle, so the scripts that run the
# suite seed it from the committed times, tests/data/ctest_cost.txt. Tests
# that are not listed there start last.
#
#   scripts/ctest_cost.sh seed BUILD      copies the committed times into BUILD, if it has none
#   scripts/ctest_cost.sh save BUILD      writes BUILD's measured times (after a whole ctest run)
#                                         into tests/data/ctest_cost.txt, rounded to 0.1 s
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
committed="$root/tests/data/ctest_cost.txt"
[ $# -eq 2 ] || { echo "usage: scripts/ctest_cost.sh seed|save BUILD" >&2; exit 1; }
kept="$2/Testing/Temporary/CTestCostData.txt"
case "$1" in
  seed)
    if [ ! -s "$kept" ]; then
      mkdir -p "$(dirname "$kept")"
      cp "$committed" "$kept"
    fi ;;
  save)
    [ -s "$kept" ] || { echo "scripts/ctest_cost.sh: $kept: no measured times (run ctest in $2 first)" >&2; exit 1; }
    # "NAME RUNS SECONDS" lines up to "---" (the failed tests follow it).
    awk '$0 == "---" { exit } NF == 3 { printf "%s 1 %.1f\n", $1, $3 }' "$kept" | sort > "$committed.tmp"
    echo "---" >> "$committed.tmp"
    mv "$committed.tmp" "$committed"
    echo "wrote $(($(wc -l < "$committed") - 1)) test times to $committed" ;;
  *) echo "scripts/ctest_cost.sh: unknown action '$1' (seed or save)" >&2; exit 1 ;;
esac
