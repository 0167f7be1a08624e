#!/usr/bin/env bash
# Runs one libFuzzer target of the `fuzz` preset for a bounded time.
#
#   tests/fuzz/fuzz.sh TARGET SECONDS WORKDIR [libFuzzer options...]
#
# SECONDS is wall-clock time (-max_total_time); with VIGIL_FUZZ_CPU=1 it is CPU time of the
# fuzzer instead (on a loaded machine, at nice 19, wall time says little): the run is then
# stopped with SIGINT once the fuzzer has used that much CPU.
#
# TARGET: candump, trc, deployment, thresholds, can_config, http_request, shm_segment, shm_live,
#         can_link
# (tests/fuzz/CMakeLists.txt).
# WORKDIR (outside the repository) receives corpus/ (grows from run to run), seeds/ (copied from
# seeds.txt), artifacts/ (crash-*, timeout-*, oom-* inputs) and fuzz.log. The run uses
# -rss_limit_mb=2048 -timeout=10, the YAML dictionary for YAML targets (http.dict for
# http_request), and fails (exit != 0) on
# any crash, hang, out-of-memory or sanitizer report. Build first:
#   cmake --preset fuzz && cmake --build build/fuzz
# Keep every input found in tests/fuzz/regressions/TARGET/ once fixed.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
target="$1"
seconds="$2"
work="$3"
shift 3
bin="${VIGIL_FUZZ_BUILD:-$root/build/fuzz}/tests/fuzz/vigil_fuzz_$target"
[[ -x "$bin" ]] || { echo "fuzz.sh: $bin not built (cmake --preset fuzz && cmake --build build/fuzz)" >&2; exit 2; }
mkdir -p "$work/corpus" "$work/seeds" "$work/artifacts"
while read -r t pattern; do
  [[ "$t" == "$target" ]] || continue
  for f in $root/$pattern; do [[ -f "$f" ]] && cp "$f" "$work/seeds/"; done
done < <(grep -v '^#' "$root/tests/fuzz/seeds.txt")
dict=()
case "$target" in
  candump | trc | shm_segment | shm_live | can_link) ;;
  http_request) dict=(-dict="$root/tests/fuzz/http.dict") ;;
  *) dict=(-dict="$root/tests/fuzz/yaml.dict") ;;
esac
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}"
# Without -fork a crash stops the run (exit != 0), which is what CI and the campaign want.
args=("$work/corpus" "$work/seeds" "$root/tests/fuzz/regressions/$target" -rss_limit_mb=2048
      -timeout=10 -print_final_stats=1 -artifact_prefix="$work/artifacts/" "${dict[@]}" "$@")
rc=0
if [[ "${VIGIL_FUZZ_CPU:-0}" == 1 ]]; then
  "$bin" "${args[@]}" >>"$work/fuzz.log" 2>&1 &
  pid=$!
  tick=$(getconf CLK_TCK)
  while kill -0 "$pid" 2>/dev/null; do
    sleep 10
    # utime + stime of the fuzzer (fields 14 and 15 of /proc/PID/stat), in clock ticks.
    used=$(awk -v t="$tick" '{ print int(($14 + $15) / t) }' "/proc/$pid/stat" 2>/dev/null || echo 0)
    if (( used >= seconds )); then
      kill -INT "$pid" 2>/dev/null || true
      echo "fuzz.sh: $target: $used CPU seconds used, stopped" >>"$work/fuzz.log"
      break
    fi
  done
  wait "$pid" || rc=$?
  # libFuzzer exits 72 after SIGINT: a requested stop, not a finding.
  if grep -q "CPU seconds used, stopped" "$work/fuzz.log" && [[ $rc -eq 72 || $rc -eq 130 ]]; then
    rc=0
  fi
else
  "$bin" "${args[@]}" -max_total_time="$seconds" >"$work/fuzz.log" 2>&1 || rc=$?
fi
# shm_segment writes its input as /dev/shm/vigil.fuzz-<pid>.<pid>.0 and removes it after each
# input; a stop in the middle of one (SIGINT, the CPU limit) leaves it. Without a finding, remove
# those of fuzzers that are gone; with one, they stay for the post-mortem.
# shm_live does the same with /dev/shm/vigil.fuzzlive-<pid>.<pid>.0.
if [[ ($target == shm_segment || $target == shm_live) && $rc -eq 0 ]]; then
  prefix=fuzz
  [[ $target == shm_live ]] && prefix=fuzzlive
  for f in /dev/shm/vigil.$prefix-*; do
    [[ -e $f ]] || continue
    p=${f#/dev/shm/vigil.$prefix-}
    p=${p%%.*}
    kill -0 "$p" 2>/dev/null || rm -f "$f"
  done
fi
grep -E "^#[0-9]+ +(INITED|DONE)|ERROR|SUMMARY|stat::number_of_executed_units|stat::peak_rss|Test unit written" \
  "$work/fuzz.log" | sed "s/^/$target: /" || true
if [[ $rc -ne 0 ]]; then
  echo "fuzz.sh: $target failed (exit $rc); log $work/fuzz.log, inputs in $work/artifacts/" >&2
fi
exit $rc
