#!/usr/bin/env bash
# Formats every C++ source of the project with clang-format (.clang-format);
# with --check, changes nothing and exits 1 listing the files that are not
# formatted (the ctest Format.EverySourceIsClangFormatted runs this).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
clang_format="${CLANG_FORMAT:-clang-format}"
mapfile -t files < <(find rtl_models sim traces tests bench util -type f \( -name '*.h' -o -name '*.cpp' \) | sort)
if [ "${1:-}" = "--check" ]; then
  # One clang-format over every file (one process start, not one per file);
  # it reports each file that differs as "FILE:LINE:COL: error: ...".
  if ! out="$("$clang_format" --dry-run --Werror "${files[@]}" 2>&1)"; then
    mapfile -t bad < <(printf '%s\n' "$out" | sed -n 's/^\([^:]*\):[0-9]*:[0-9]*: error: .*clang-format-violations.*/\1/p' | sort -u)
    if [ ${#bad[@]} -eq 0 ]; then
      echo "clang-format failed: $out"
      exit 1
    fi
    echo "not clang-formatted (run scripts/format.sh): ${bad[*]}"
    exit 1
  fi
  echo "${#files[@]} files clang-formatted"
else
  "$clang_format" -i "${files[@]}"
fi
