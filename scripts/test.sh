#!/usr/bin/env bash
# Installs what is missing, builds and runs the whole test suite.
#   scripts/test.sh [PRESET]    PRESET: dev (default), release, asan-ubsan, tsan
set -euo pipefail
cd "$(dirname "$0")/.."
preset="${1:-dev}"
scripts/setup.sh
cmake --preset "$preset" >/dev/null
cmake --build --preset "$preset" -j "$(nproc)"
# VIGIL_CTEST_ARGS: more ctest arguments (.ci/run: one retry of a failed test on a loaded machine).
# shellcheck disable=SC2086
# VIGIL_CTEST_EXCLUDE: a regex of tests not to run (.ci/run: the TSan quarantine).
exclude=()
[[ -n "${VIGIL_CTEST_EXCLUDE:-}" ]] && exclude=(-E "$VIGIL_CTEST_EXCLUDE")
ctest --preset "$preset" -j "$(nproc)" ${VIGIL_CTEST_ARGS:-} "${exclude[@]}"
