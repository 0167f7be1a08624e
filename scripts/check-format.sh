#!/usr/bin/env bash
# Fails when a C++ file tracked by git is not formatted as .clang-format says (clang-format 14).
#   scripts/check-format.sh          check
#   scripts/check-format.sh --fix    reformat in place
set -euo pipefail
cd "$(dirname "$0")/.."
cf=$(command -v clang-format-14 || command -v clang-format)
mapfile -t files < <(git ls-files -co --exclude-standard '*.hpp' '*.cpp' | grep -v '^build/' || true)
[[ ${#files[@]} -gt 0 ]] || exit 0
if [[ "${1:-}" == "--fix" ]]; then
  "$cf" -i "${files[@]}"
else
  "$cf" --dry-run -Werror "${files[@]}"
  echo "format: ${#files[@]} files clean"
fi
