#!/usr/bin/env bash
# Installs every Debian 12 package that vigil's build, tests, examples and benchmarks need.
# Idempotent: it calls apt-get only when a package is missing. Needs root (or sudo) for that case.
#
#   scripts/setup.sh            build + test + bench dependencies
#   scripts/setup.sh --check    list what is missing, install nothing (exit 1 if anything is)
set -euo pipefail

packages=(
  # toolchain
  g++ cmake ninja-build pkg-config clang-format-14 git ccache
  # static analysis: the tidy preset (.clang-tidy) needs clang-tidy 16 for GCC 12's std::expected
  clang-tidy-16
  # libraries
  libboost-dev libfmt-dev libyaml-cpp-dev libcpp-httplib-dev libcli11-dev
  # tests and benchmarks
  catch2 libbenchmark-dev can-utils rt-tests python3
  # the dashboard's charts (embedded at build time) and the HTTP end-to-end tests: a real
  # browser, Prometheus (and promtool), the OpenMetrics parser, ss
  libjs-chart.js chromium prometheus python3-prometheus-client iproute2
  # the LTTng-UST comparison row of benches/task (tracepoint provider and session control)
  liblttng-ust-dev lttng-tools
  # fuzzing (the `fuzz` preset: libFuzzer needs clang; clang-14 cannot compile libstdc++ 12's
  # std::expected, clang-16 can)
  clang-16 libfuzzer-16-dev libclang-rt-16-dev
  # the logging benchmark's peer only, never linked by vigil
  libspdlog-dev
  # instruction counts of the per-cycle path (scripts/callgrind-cycle.sh, docs/performance.md)
  valgrind
  # vigil as a package of a ROS 2 workspace (tests/colcon/colcon_build.sh, docs/guide/colcon.md):
  # colcon, its CMake builds, package.xml, and its `list` verb
  colcon python3-colcon-cmake python3-colcon-ros python3-colcon-package-information
  # ROS 2 /diagnostics over DDS (docs/guide/ros2.md): Cyclone DDS and its IDL compiler for the
  # output (optional: without them the output only warns), Fast DDS for the tests' second
  # subscriber
  cyclonedds-dev cyclonedds-tools libfastrtps-dev
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [[ ${#missing[@]} -eq 0 ]]; then
  echo "setup: all ${#packages[@]} packages present"
  exit 0
fi

if [[ "${1:-}" == "--check" ]]; then
  echo "setup: missing: ${missing[*]}"
  exit 1
fi

echo "setup: installing ${missing[*]}"
sudo_cmd=()
if [[ $(id -u) -ne 0 ]]; then
  command -v sudo >/dev/null || { echo "setup: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
  sudo_cmd=(sudo)
fi
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
"${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "setup: done"
