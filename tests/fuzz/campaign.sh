#!/usr/bin/env bash
# A long fuzzing campaign: every target until it has used CPU_SECONDS of CPU, two at a time, at
# the lowest priority (nice 19), each in WORKROOT/TARGET (corpus, artifacts, fuzz.log).
#
#   tests/fuzz/campaign.sh WORKROOT CPU_SECONDS [TARGET...]     (default: every target)
#
# Progress: WORKROOT/campaign.log; figures per target: tests/fuzz/figures.sh WORKROOT.
set -uo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
work="$1"
cpu="$2"
shift 2
targets=("$@")
[[ ${#targets[@]} -gt 0 ]] || targets=(candump trc deployment thresholds can_config http_request shm_segment can_link)
mkdir -p "$work"
export VIGIL_FUZZ_CPU=1 root work cpu
printf '%s\n' "${targets[@]}" | xargs -P 2 -I{} bash -c '
  echo "$(date -Is) start {}" >>"$work/campaign.log"
  nice -n 19 "$root/tests/fuzz/fuzz.sh" {} "$cpu" "$work/{}" >"$work/{}.summary" 2>&1
  echo "$(date -Is) end {} exit $?" >>"$work/campaign.log"'
