#!/usr/bin/env bash
# Installs what is missing, builds (Release) and runs vigil's main job, `vigil demo`: a simulated
# robot under supervision with a live view, for 20 s by default (Ctrl-C stops it earlier).
#   scripts/demo.sh [ARGS...]   extra arguments go to the program
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
cmake --preset release >/dev/null
cmake --build --preset release -j "$(nproc)" --target vigil_cli   # only what the demo needs
exec build/release/apps/vigil/vigil demo "$@"
