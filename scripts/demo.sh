#!/usr/bin/env bash
# Installs what is missing, builds (Release) and runs vigil's main job for a bounded time.
#   scripts/demo.sh [ARGS...]   extra arguments go to the program
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
cmake --preset release >/dev/null
cmake --build --preset release -j "$(nproc)"
exec build/release/examples/platform_check/platform_check "$@"
