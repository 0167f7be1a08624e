#!/usr/bin/env bash
# The demo's resident memory with memory locked stays under the goal (issue 21 item 5; figures and
# breakdown in docs/design/memory.md). A regression guard: the HTTP libraries once made every
# program resident for 6.6 MB more without anyone noticing.
#   demo_memory.sh VIGIL [LIMIT_KIB]    (default limit: 24 MiB = 24576 KiB)
# Reads /proc/<pid>/status 4.5 s into a 6-second `vigil demo --no-live`. Exits 77 (skipped),
# saying why, when memory could not be locked (not root, or RLIMIT_MEMLOCK too small): unlocked,
# VmRSS measures only the pages touched.
set -euo pipefail
vigil=${1:?usage: demo_memory.sh VIGIL [LIMIT_KIB]}
limit=${2:-24576}
[[ $limit =~ ^[0-9]+$ ]] || { echo "demo_memory.sh: LIMIT_KIB '$limit' is not a number" >&2; exit 2; }
out=$(mktemp)
trap 'rm -f "$out"' EXIT
"$vigil" demo --duration 6 --no-live >"$out" 2>&1 &
pid=$!
sleep 4.5
status=$(cat "/proc/$pid/status" 2>/dev/null || true)
wait "$pid" || { echo "FAIL: the demo exited with $?:"; tail -20 "$out"; exit 1; }
rss=$(awk '/^VmRSS:/ {print $2}' <<<"$status")
lck=$(awk '/^VmLck:/ {print $2}' <<<"$status")
[[ -n $rss && -n $lck ]] || { echo "FAIL: the demo was not running 4.5 s after its start"; tail -20 "$out"; exit 1; }
echo "VmRSS ${rss} kB, VmLck ${lck} kB (limit ${limit} kB)"
if (( lck < rss / 2 )); then
  echo "SKIP: memory is not locked (VmLck ${lck} kB): run as root, or raise RLIMIT_MEMLOCK"
  exit 77
fi
if (( rss >= limit )); then
  echo "FAIL: the demo holds ${rss} kB resident, the goal is under ${limit} kB;" \
       "see docs/design/memory.md for what to look at (/proc/<pid>/smaps)"
  exit 1
fi
