#!/usr/bin/env bash
# Builds vigil as a package of a colcon workspace (a ROS 2 robot's way to build) with a second
# package that finds it with find_package(vigil) and links a component, then runs that package's
# program. The workspace is build/colcon-ws (or $1): src/ holds links to this checkout and to
# tests/colcon/consumer. Only vigil's libraries are built (no tests, benchmarks, examples or
# tool), through ccache when installed, as the dev preset would: a few minutes cold, under one
# with a warm cache. docs/guide/colcon.md; run by .ci/run.
#
#   tests/colcon/colcon_build.sh [WORKSPACE]
#
# Exit 77 (skipped) with the reason when colcon or its CMake and package.xml support is missing
# (scripts/setup.sh installs them). VIGIL_COLCON_JOBS sets the parallel jobs (default: all CPUs).
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
ws="${1:-$root/build/colcon-ws}"

if ! command -v colcon >/dev/null; then
  echo "skipped: colcon is not installed (Debian: colcon python3-colcon-cmake python3-colcon-ros; scripts/setup.sh)"
  exit 77
fi
# The verbs and extensions used below: `list` (python3-colcon-package-information), the CMake
# build (python3-colcon-cmake), package.xml (python3-colcon-ros: the packages' type ros.cmake).
if ! colcon list --help >/dev/null 2>&1; then
  echo "skipped: colcon has no 'list' verb (Debian: python3-colcon-package-information; scripts/setup.sh)"
  exit 77
fi
if ! colcon build --help 2>/dev/null | grep -q -- --cmake-args; then
  echo "skipped: colcon cannot build CMake packages (Debian: python3-colcon-cmake; scripts/setup.sh)"
  exit 77
fi

# package.xml and the project must agree on the version.
project_version="$(sed -n '/^project(vigil/,/)/s/.*VERSION \([0-9.]*\).*/\1/p' "$root/CMakeLists.txt")"
package_version="$(sed -n 's:.*<version>\(.*\)</version>.*:\1:p' "$root/package.xml")"
if [[ "$project_version" != "$package_version" ]]; then
  echo "package.xml says version $package_version, CMakeLists.txt's project() $project_version" >&2
  exit 1
fi

mkdir -p "$ws/src"
ln -sfn "$root" "$ws/src/vigil"
ln -sfn "$root/tests/colcon/consumer" "$ws/src/vigil_colcon_consumer"
cd "$ws"

# What colcon finds: exactly the two packages, each through its package.xml (type ros.cmake;
# plain "cmake" means colcon-ros is missing and package.xml is ignored). The checkout's own
# build/ and tests/ are not crawled below a package.
listed="$(colcon list --base-paths src | awk '{print $1, $3}' | sort | tr '\n' ' ')"
if [[ "$listed" == *"(cmake)"* ]]; then
  echo "skipped: colcon reads no package.xml (Debian: python3-colcon-ros; scripts/setup.sh)"
  exit 77
fi
if [[ "$listed" != "vigil (ros.cmake) vigil_colcon_consumer (ros.cmake) " ]]; then
  echo "colcon found: $listed (expected: vigil and vigil_colcon_consumer, type ros.cmake)" >&2
  exit 1
fi

# Cyclone DDS is an optional dependency (package.xml, a REP 149 condition): declared only when
# the environment sets VIGIL_WITH_CYCLONEDDS=1.
build_deps() { colcon info --base-paths src vigil | sed -n 's/^ *build: //p'; }
without=" $(build_deps) "
with=" $(VIGIL_WITH_CYCLONEDDS=1 build_deps) "
if [[ "$without" == *" cyclonedds "* || "$with" != *" cyclonedds "* ]]; then
  echo "cyclonedds: expected only with VIGIL_WITH_CYCLONEDDS=1; build dependencies were" \
    "'$without' without it, '$with' with it" >&2
  exit 1
fi

jobs="${VIGIL_COLCON_JOBS:-$(nproc)}"
# The library targets only: the options of cmake/VigilOptions.cmake that default to ON for a
# top-level project (which vigil is here) are turned off, apart from the install.
MAKEFLAGS="-j${jobs}" colcon build --base-paths src --executor sequential \
  --event-handlers console_direct+ \
  --cmake-args -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DVIGIL_BUILD_TESTS=OFF -DVIGIL_BUILD_BENCHES=OFF -DVIGIL_BUILD_EXAMPLES=OFF \
    -DVIGIL_BUILD_APPS=OFF -DVIGIL_CCACHE=ON

# What a ROS 2 user does next: source the workspace (colcon's sh script), run the program.
set +u
# shellcheck disable=SC1091
. "$ws/install/setup.sh"
set -u
[[ -n "$(find "$ws/install/vigil" -name vigil-config.cmake -print -quit)" ]]
"$ws/install/vigil_colcon_consumer/lib/vigil_colcon_consumer/vigil_colcon_consumer"
echo "colcon workspace: vigil and vigil_colcon_consumer built and run in $ws"
