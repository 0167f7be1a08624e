#!/usr/bin/env bash
# The demo's resident memory with memory locked stays under the goal (issue 21 item 5; figures and
# breakdown in docs/design/memory.md). A regression guard: the HTTP libraries once made every
# program resident for 6.6 MB more without anyone noticing.
#   demo_memory.sh VIGIL [LIMIT_KIB] [HTTP_LOCKED_LIMIT_KIB]
# Reads /proc/<pid>/status 4.5 s into a 6-second `vigil demo --no-live`:
# - without `--http`, VmRSS must stay under LIMIT_KIB (default 24 MiB = 24576 KiB);
# - with `--http 0`, VmLck must stay under HTTP_LOCKED_LIMIT_KIB (default 40 MiB = 40960 KiB): the
#   HTTP threads start before the rest of the real-time set-up, and when they did so before the
#   malloc arenas were bounded they got an arena of their own, whose 64 MiB reserve mlockall
#   counted (VmLck 92 MB).
# Exits 77 (skipped), saying why, when memory could not be locked (not root, or RLIMIT_MEMLOCK too
# small): unlocked, VmRSS measures only the pages touched.
set -euo pipefail
vigil=${1:?usage: demo_memory.sh VIGIL [LIMIT_KIB] [HTTP_LOCKED_LIMIT_KIB]}
limit=${2:-24576}
http_limit=${3:-40960}
for n in "$limit" "$http_limit"; do
  [[ $n =~ ^[0-9]+$ ]] || { echo "demo_memory.sh: limit '$n' is not a number of KiB" >&2; exit 2; }
done
out=$(mktemp)
trap 'rm -f "$out"' EXIT

# measure ARGS...: runs the demo with ARGS, sets rss and lck (kB).
measure() {
  "$vigil" demo --duration 6 --no-live "$@" >"$out" 2>&1 &
  local pid=$!
  sleep 4.5
  local status
  status=$(cat "/proc/$pid/status" 2>/dev/null || true)
  wait "$pid" || { echo "FAIL: vigil demo $* exited with $?:"; tail -20 "$out"; exit 1; }
  rss=$(awk '/^VmRSS:/ {print $2}' <<<"$status")
  lck=$(awk '/^VmLck:/ {print $2}' <<<"$status")
  [[ -n $rss && -n $lck ]] ||
    { echo "FAIL: vigil demo $* was not running 4.5 s after its start"; tail -20 "$out"; exit 1; }
}

measure
echo "without --http: VmRSS ${rss} kB, VmLck ${lck} kB (limit ${limit} kB resident)"
if (( lck < rss / 2 )); then
  echo "SKIP: memory is not locked (VmLck ${lck} kB): run as root, or raise RLIMIT_MEMLOCK"
  exit 77
fi
if (( rss >= limit )); then
  echo "FAIL: the demo holds ${rss} kB resident, the goal is under ${limit} kB;" \
       "see docs/design/memory.md for what to look at (/proc/<pid>/smaps)"
  exit 1
fi

measure --http 0
echo "with --http 0: VmRSS ${rss} kB, VmLck ${lck} kB (limit ${http_limit} kB locked)"
if (( lck >= http_limit )); then
  echo "FAIL: with --http the demo locks ${lck} kB, more than ${http_limit} kB: a thread started" \
       "before the malloc arenas were bounded has an arena of its own (a 64 MiB reserve in" \
       "/proc/<pid>/smaps); see docs/design/memory.md"
  exit 1
fi
