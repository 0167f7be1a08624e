#!/usr/bin/env bash
# Fails when a module's header or source includes a module above its own (docs/design/modules.md).
#   scripts/check-layering.sh [ROOT]     ROOT: the tree to check (default: this repository)
#
# The module of a file is its folder: include/vigil/<module>/... or src/<module>/...; the files
# directly in include/vigil/ (error.hpp, expected.hpp, assert.hpp, build_config.hpp, version.hpp)
# count as the platform level, except the umbrella vigil/vigil.hpp, which includes everything.
# An include names its module the same way: "vigil/<module>/..." ("vigil/<file>.hpp": platform).
#
# It also checks that each src/<module>/CMakeLists.txt links (DEPS + PRIVATE_DEPS) exactly the
# vigil modules that the module's files include, so the CMake graph and the include graph agree.
set -euo pipefail
root="${1:-$(cd "$(dirname "$0")/.." && pwd)}"

# The graph: what each module may include (already closed under "below": every module listed is
# below the one on the left). A module missing from this table is an error, so that a new module
# gets its place here.
#   platform <- bus <- log <- health <- task <- exec <- supervisor <- monitor <- export/service <- deploy
#   config (beside, on platform) is used by monitor, can, deploy; can sits beside monitor and is
#   used by export and deploy; alloc_guard is the platform's opt-in malloc interposer.
declare -A allowed=(
  [platform]="platform"
  [alloc_guard]="platform"
  [bus]="platform"
  [log]="platform bus"
  [health]="platform bus"
  [task]="platform bus log health"
  [exec]="platform bus log health task"
  [supervisor]="platform bus log health task exec"
  [config]="platform"
  [monitor]="platform bus log health task exec supervisor config"
  [can]="platform bus log health task exec supervisor monitor config"
  [export]="platform bus log health task exec supervisor monitor config can"
  [service]="platform bus log health task exec supervisor monitor config can export"
  [deploy]="platform bus log health task exec supervisor monitor config can export service"
)
# Known violations, to be removed (module:included-module).
known=()

fail=0
is_known() {
  local k
  for k in "${known[@]}"; do [[ "$k" == "$1" ]] && return 0; done
  return 1
}
module_of() {  # path relative to root -> module ("" for the umbrella)
  local f="$1" rest
  case "$f" in
    include/vigil/vigil.hpp) echo "" ;;
    include/vigil/*/*) rest="${f#include/vigil/}"; echo "${rest%%/*}" ;;
    include/vigil/*) echo "platform" ;;
    src/*/*) rest="${f#src/}"; echo "${rest%%/*}" ;;
    *) echo "" ;;
  esac
}

declare -A used=()  # "<module> <included>" -> 1
cd "$root"
while IFS= read -r -d '' f; do
  f="${f#./}"
  m="$(module_of "$f")"
  [[ -z "$m" ]] && continue
  if [[ -z "${allowed[$m]+x}" ]]; then
    echo "$f: module '$m' is not in scripts/check-layering.sh's table: give it its place" >&2
    fail=1
    continue
  fi
  while IFS=: read -r line inc; do
    inc="${inc#*\"vigil/}"
    inc="${inc%%\"*}"
    if [[ "$inc" == */* ]]; then im="${inc%%/*}"; else im="platform"; fi
    [[ "$im" == "$m" ]] && continue
    used["$m $im"]=1
    if [[ " ${allowed[$m]} " != *" $im "* ]]; then
      if is_known "$m:$im"; then continue; fi
      echo "$f:$line: module '$m' includes \"vigil/$inc\" from module '$im', which is not below" \
        "it (allowed: ${allowed[$m]})" >&2
      fail=1
    fi
  done < <(grep -n -E '^[[:space:]]*#[[:space:]]*include[[:space:]]*"vigil/' "$f" || true)
done < <(find include/vigil src -type f \( -name '*.hpp' -o -name '*.cpp' -o -name '*.h' \) -print0)

# CMake: each module's vigil:: link dependencies are exactly the modules it includes.
for cm in src/*/CMakeLists.txt; do
  m="$(basename "$(dirname "$cm")")"
  [[ -z "${allowed[$m]+x}" ]] && continue
  # The vigil_add_module(...) call, comments dropped, on one line.
  call="$(sed -e 's/#.*//' "$cm" | tr '\n' ' ' | grep -o 'vigil_add_module([^)]*)' || true)"
  [[ -z "$call" ]] && continue
  # Every target the folder defines counts (deploy also builds deploy_can); a link to the
  # module's own target (deploy_can -> deploy) is not an include of another module.
  linked="$(grep -o 'vigil::[a-z_]*' <<<"$call" | sed 's/vigil:://' | grep -vx "$m" | sort -u |
    tr '\n' ' ')"
  included=""
  for k in "${!used[@]}"; do
    [[ "${k%% *}" == "$m" ]] && included+="${k#* } "
  done
  included="$(tr ' ' '\n' <<<"$included" | sed '/^$/d' | sort -u | tr '\n' ' ')"
  if [[ "$linked" != "$included" ]]; then
    echo "$cm: links vigil modules [${linked% }] but its files include [${included% }]:" \
      "make DEPS/PRIVATE_DEPS list exactly what it includes" >&2
    fail=1
  fi
done

if [[ $fail -ne 0 ]]; then
  echo "layering: FAILED (see docs/design/modules.md for the graph)" >&2
  exit 1
fi
echo "layering: every include and every module's DEPS follow the module graph"
