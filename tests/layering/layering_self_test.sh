#!/usr/bin/env bash
# Proves that scripts/check-layering.sh fails on a bad tree: copies include/ and src/ of the
# repository to a scratch folder, checks that the copy passes, then plants one violation at a time
# (a bus header that includes a task header; a task module whose CMake DEPS forget a module it
# includes) and expects the check to fail naming the file.
#   tests/layering/layering_self_test.sh REPO SCRATCH
set -euo pipefail
repo="$1"
scratch="$2/layering_self_test"
check="$repo/scripts/check-layering.sh"
rm -rf "$scratch"
mkdir -p "$scratch"

fresh_copy() {
  rm -rf "$scratch/tree"
  mkdir -p "$scratch/tree"
  cp -r "$repo/include" "$repo/src" "$scratch/tree/"
}

fresh_copy
if ! "$check" "$scratch/tree" >"$scratch/clean.log" 2>&1; then
  echo "FAIL: the unchanged copy should pass:" >&2
  cat "$scratch/clean.log" >&2
  exit 1
fi

# 1. A bus header includes a task header: bus is below task.
fresh_copy
printf '#pragma once\n#include "vigil/task/messages.hpp"\n' >"$scratch/tree/include/vigil/bus/bad.hpp"
if "$check" "$scratch/tree" >"$scratch/bus.log" 2>&1; then
  echo "FAIL: a bus header including a task header was not caught" >&2
  exit 1
fi
grep -q 'include/vigil/bus/bad.hpp:2: module .bus. includes "vigil/task/messages.hpp"' \
  "$scratch/bus.log" || { echo "FAIL: the report does not name bus/bad.hpp:2:" >&2; cat "$scratch/bus.log" >&2; exit 1; }

# 2. A task source includes the supervisor (the upward include this layering removed).
fresh_copy
printf '#include "vigil/supervisor/component_aggregator.hpp"\n' >"$scratch/tree/src/task/bad.cpp"
if "$check" "$scratch/tree" >"$scratch/task.log" 2>&1; then
  echo "FAIL: a task source including a supervisor header was not caught" >&2
  exit 1
fi
grep -q 'src/task/bad.cpp:1: module .task.' "$scratch/task.log" ||
  { echo "FAIL: the report does not name src/task/bad.cpp:1:" >&2; cat "$scratch/task.log" >&2; exit 1; }

# 3. A module's CMake DEPS do not list a module it includes.
fresh_copy
sed -i 's/DEPS vigil::platform vigil::task)/DEPS vigil::task)/' "$scratch/tree/src/exec/CMakeLists.txt"
grep -q 'DEPS vigil::task)' "$scratch/tree/src/exec/CMakeLists.txt" ||
  { echo "FAIL: could not plant the DEPS change (src/exec/CMakeLists.txt changed?)" >&2; exit 1; }
if "$check" "$scratch/tree" >"$scratch/deps.log" 2>&1; then
  echo "FAIL: exec's DEPS without vigil::platform were not caught" >&2
  exit 1
fi
grep -q 'src/exec/CMakeLists.txt: links vigil modules' "$scratch/deps.log" ||
  { echo "FAIL: the report does not name src/exec/CMakeLists.txt" >&2; cat "$scratch/deps.log" >&2; exit 1; }

echo "layering self-test: the check passes the tree and fails each planted violation"
