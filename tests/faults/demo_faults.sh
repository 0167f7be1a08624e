#!/usr/bin/env bash
# Faults around `vigil demo`, end to end (CTest: faults.demo_*). Exit codes: apps/vigil/commands.hpp.
#
#   demo_faults.sh VIGIL WORKDIR CASE [DEPLOYMENT]
#
# CASE:
#   sigterm, sigint  the signal arrives while the demo runs (no --duration): exit 0, "Interrupted",
#                    the final report printed and the JSON file written and complete;
#   unwritable       --json into a directory that cannot hold it (a path under a regular file,
#                    which fails even for root): an error naming the path at start, the run goes
#                    on to its end, the report is printed, then exit 3 with the path and reason;
#   disk_full        --json /dev/full: the write fails with "No space left on device": exit 3;
#   stuck            DEPLOYMENT has a component stuck forever in on_update (demo.stuck): its
#                    thread-mate starves with it, a component elsewhere runs on; stopping cannot
#                    join that thread: after 5 s the demo prints and writes the monitor's latest
#                    reports and exits 4.
set -uo pipefail
vigil="$1"
work="$2"
case="$3"
deployment="${4:-}"
rm -rf "$work"
mkdir -p "$work"
out="$work/out.txt"
err="$work/err.txt"
json="$work/final.json"
fail() {
  echo "FAILED ($case): $*"
  echo "--- stdout"; cat "$out"; echo "--- stderr"; cat "$err"
  exit 1
}
# JSON checks: python3 reads the file; prints nothing and exits 0 when every assertion holds.
check_json() {
  python3 - "$1" "$2" <<'PY' || fail "JSON check: $2"
import json, sys
with open(sys.argv[1]) as f:
    d = json.load(f)
assert d["schema"] == 2, d["schema"]
by = {c["name"]: c for c in d["components"]}
exec(sys.argv[2])
PY
}
# Waits until the demo printed its first line (signals are handled from then on).
wait_running() {
  for _ in $(seq 1 200); do
    grep -q "^vigil .*: running" "$out" 2>/dev/null && return 0
    kill -0 "$1" 2>/dev/null || return 1
    sleep 0.1
  done
  return 1
}

case "$case" in
  sigterm | sigint)
    sig=TERM
    [[ "$case" == sigint ]] && sig=INT
    "$vigil" demo --duration 0 --no-live --json "$json" >"$out" 2>"$err" &
    pid=$!
    wait_running "$pid" || fail "the demo did not start"
    sleep 3
    kill -s "$sig" "$pid"
    wait "$pid"
    rc=$?
    [[ $rc -eq 0 ]] || fail "exit code $rc, expected 0 after SIG$sig"
    grep -q "^Interrupted after" "$out" || fail "no 'Interrupted after' line"
    grep -q "motor_left" "$out" || fail "no final report"
    grep -q "Final reports written to $json" "$out" || fail "JSON not reported written"
    check_json "$json" 'assert by["motor_left"]["counters"]["cycles"] > 100; assert by["vigil.supervisor"]["status"] == "OK"'
    ;;
  unwritable)
    touch "$work/file"
    bad="$work/file/final.json"
    "$vigil" demo --duration 2 --no-live --json "$bad" >"$out" 2>"$err"
    rc=$?
    [[ $rc -eq 3 ]] || fail "exit code $rc, expected 3"
    grep -q "cannot write $bad: Not a directory; supervision goes on" "$err" || fail "no early error naming the path"
    grep -q "cannot write the final reports to $bad: Not a directory" "$err" || fail "no final error naming the path"
    grep -q "^Stopped after 2" "$out" || fail "the run did not go on to its end"
    grep -q "motor_left" "$out" || fail "no final report printed"
    ;;
  disk_full)
    [[ -w /dev/full ]] || { echo "skipped: /dev/full absent"; exit 0; }
    "$vigil" demo --duration 1 --no-live --json /dev/full >"$out" 2>"$err"
    rc=$?
    [[ $rc -eq 3 ]] || fail "exit code $rc, expected 3"
    grep -q "cannot write the final reports to /dev/full: No space left on device" "$err" || fail "no error naming /dev/full and ENOSPC"
    grep -q "motor_left" "$out" || fail "no final report printed"
    ;;
  stuck)
    start=$SECONDS
    timeout 60 "$vigil" demo --config "$deployment" --duration 4 --no-live --json "$json" >"$out" 2>"$err"
    rc=$?
    [[ $rc -eq 4 ]] || fail "exit code $rc, expected 4"
    (( SECONDS - start < 30 )) || fail "took $((SECONDS - start)) s"
    grep -q "did not stop within 5 s: a component is stuck in on_update (STALE: hanging, neighbour)" "$err" || fail "no message naming the stuck components"
    grep -q "not stopped. Latest report:" "$out" || fail "no latest report printed"
    check_json "$json" '
assert by["hanging"]["status"] == "STALE", by["hanging"]["status"]
assert by["neighbour"]["status"] == "STALE", by["neighbour"]["status"]
assert by["hanging"]["messages"][0].startswith("starved: no cycle for"), by["hanging"]["messages"]
assert by["hanging"]["tid"] == by["neighbour"]["tid"]
assert by["elsewhere"]["status"] in ("OK", "WARN"), by["elsewhere"]["status"]
assert by["elsewhere"]["tid"] != by["hanging"]["tid"]
assert by["elsewhere"]["state"] in ("Running", "Stopped"), by["elsewhere"]["state"]
assert by["vigil.supervisor"]["status"] == "OK"'
    ;;
  *)
    echo "unknown case $case" >&2
    exit 2
    ;;
esac
echo "PASSED ($case)"
