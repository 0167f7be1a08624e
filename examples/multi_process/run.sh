#!/usr/bin/env bash
# examples/multi_process/run.sh [BUILD_DIR]: starts `vigil supervise`, two controllers and a
# driver with VIGIL_SUPERVISOR set, kills the arm controller with kill -9 after 3 s, and lets the
# daemon report for 6 s in all. BUILD_DIR defaults to build/dev; it needs the targets vigil_cli,
# multi_process_controller and multi_process_driver.
set -euo pipefail

build=${1:-build/dev}
name=${VIGIL_EXAMPLE_NAME:-robot}
vigil=$build/apps/vigil/vigil
ctl=$build/examples/multi_process/controller
drv=$build/examples/multi_process/driver
for b in "$vigil" "$ctl" "$drv"; do
  [[ -x $b ]] || { echo "run.sh: $b is missing: cmake --build $build --target vigil_cli" \
                        "multi_process_controller multi_process_driver" >&2; exit 1; }
done

"$vigil" supervise --name "$name" --no-live --duration 6 --color never &
daemon=$!
sleep 0.5
VIGIL_SUPERVISOR=$name "$ctl" arm &
arm=$!
VIGIL_SUPERVISOR=$name "$ctl" leg &
leg=$!
VIGIL_SUPERVISOR=$name "$drv" &
driver=$!

sleep 3
echo "--- kill -9 $arm (the arm controller)"
kill -9 "$arm"
wait "$daemon" || true
kill "$leg" "$driver"
wait "$leg" "$driver" 2> /dev/null || true
echo "--- segments of '$name' left in /dev/shm:"
ls /dev/shm | grep "^vigil\.$name\." || echo "(none)"
