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
  bad=()
  for f in "${files[@]}"; do
    "$clang_format" --dry-run --Werror "$f" >/dev/null 2>&1 || bad+=("$f")
  done
  if [ ${#bad[@]} -gt 0 ]; then
    echo "not clang-formatted (run scripts/format.sh): ${bad[*]}"
    exit 1
  fi
  echo "${#files[@]} files clang-formatted"
else
  "$clang_format" -i "${files[@]}"
fi
