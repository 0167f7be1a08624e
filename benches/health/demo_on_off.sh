#!/usr/bin/env bash
# Wake-up latency of the demo's 1 kHz and 500 Hz SCHED_FIFO components with a feature on and off,
# in one run: health supervision (issue 45, "Cost, measured") or the ROS 2 output (issue 47,
# "Measured").
#
#   benches/health/demo_on_off.sh [-m health|ros2] [-b path/to/vigil] [-r rounds] [-D seconds]
#                                 [-l path/to/vigil_ros2_listener] [-o dir]
#
# -m health (the default): "on" is the built-in demo deployment (`vigil demo --print-config`: its
# `health:` section supervises four supervisions and the gripper, logger, encoder and telemetry
# pass checkpoints); "off" is the same file without the `health:` section (the checkpoints are
# still passed and drained, nothing judges them).
# -m ros2: "on" is the built-in deployment with `--ros2` (/diagnostics over Cyclone DDS at every
# monitor cycle and event), "off" the same without; both in a domain of their own on loopback
# (ROS_DOMAIN_ID, CYCLONEDDS_URI as tests/export/ros2_demo_test.sh). With -l, the suite's Cyclone
# listener (build/dev/tests/export/vigil_ros2_listener) subscribes during the "on" runs, so the
# samples are serialised and sent, not only written. Needs a vigil built with Cyclone DDS.
# Rounds alternate off, on, off, on... so that drift in the
# machine's load falls on both. Each run writes its final JSON; the healthy FIFO components'
# (motor_left, motor_right: 1 kHz, priority 80; sensor_fusion: 500 Hz, priority 70) latency
# p50/p99/max are printed per run, then the median over the rounds of each, and the ratio on/off.
# The last line is machine-readable:
#   RESULT off_p99_us=.. on_p99_us=.. ratio=..   (medians of the motors' p99 over the rounds)
# Use a Release build (build/release/apps/vigil/vigil): a dev build measures the assertions.
set -euo pipefail

vigil=build/release/apps/vigil/vigil
mode_of_test=health
listener=""
rounds=5
duration=8
out=""
while getopts "m:b:r:D:l:o:" opt; do
  case $opt in
    m) mode_of_test=$OPTARG ;;
    b) vigil=$OPTARG ;;
    r) rounds=$OPTARG ;;
    D) duration=$OPTARG ;;
    l) listener=$OPTARG ;;
    o) out=$OPTARG ;;
    *) sed -n '2,32p' "$0"; exit 2 ;;
  esac
done
case $mode_of_test in
  health | ros2) ;;
  *) echo "demo_on_off.sh: -m $mode_of_test: expected health or ros2" >&2; exit 2 ;;
esac
[[ -z $listener || -x $listener ]] || { echo "demo_on_off.sh: -l $listener is not a program" >&2;
                                         exit 2; }
[[ -x $vigil ]] || { echo "demo_on_off.sh: $vigil is missing (cmake --preset release &&" \
                          "cmake --build build/release --target vigil_cli)" >&2; exit 1; }
if [[ -z $out ]]; then
  out=$(mktemp -d)
  trap 'rm -rf "$out"' EXIT
fi
mkdir -p "$out"

"$vigil" demo --print-config > "$out/on.yaml"
extra_on=()
if [[ $mode_of_test == ros2 ]]; then
  cp "$out/on.yaml" "$out/off.yaml"
  extra_on=(--ros2)
  ROS_DOMAIN_ID=$((100 + RANDOM % 100))
  export ROS_DOMAIN_ID
  export CYCLONEDDS_URI='<CycloneDDS><Domain id="any"><General><Interfaces><NetworkInterface name="lo"/></Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>20</MaxAutoParticipantIndex><Peers><Peer address="127.0.0.1"/></Peers></Discovery></Domain></CycloneDDS>'
else
python3 - "$out/on.yaml" "$out/off.yaml" <<'PY'
import sys
lines = open(sys.argv[1]).read().splitlines(keepends=True)
keep, skipping = [], False
for line in lines:
    if line.startswith("health:"):
        skipping = True
        continue
    if skipping and (line.startswith(" ") or line.startswith("\t") or not line.strip()):
        continue
    skipping = False
    keep.append(line)
open(sys.argv[2], "w").write("".join(keep))
PY
grep -q '^health:' "$out/off.yaml" && { echo "demo_on_off.sh: could not strip health:" >&2; exit 1; }
fi

for ((i = 1; i <= rounds; ++i)); do
  for mode in off on; do
    args=()
    listener_pid=""
    if [[ $mode == on ]]; then
      args=("${extra_on[@]}")
      if [[ -n $listener ]]; then
        "$listener" "$ROS_DOMAIN_ID" 1000000 $((duration + 10)) > "$out/listener-$i.jsonl" \
          2> "$out/listener-$i.err" &
        listener_pid=$!
      fi
    fi
    "$vigil" demo --config "$out/$mode.yaml" --duration "$duration" --no-live \
      ${args[@]+"${args[@]}"} --json "$out/$mode-$i.json" > "$out/$mode-$i.log" 2>&1 || true
    if [[ -n $listener_pid ]]; then
      kill "$listener_pid" 2> /dev/null || true
      wait "$listener_pid" 2> /dev/null || true
      samples=$(wc -l < "$out/listener-$i.jsonl")
      [[ $samples -gt 0 ]] || { echo "demo_on_off.sh: the listener received nothing in round" \
                                       "$i" >&2; cat "$out/listener-$i.err" >&2; exit 1; }
      echo "round $i: the listener received $samples /diagnostics samples"
    fi
    [[ -s $out/$mode-$i.json ]] || { echo "demo_on_off.sh: no JSON from $mode round $i:" >&2;
                                      tail -20 "$out/$mode-$i.log" >&2; exit 1; }
  done
done

python3 - "$out" "$rounds" <<'PY'
import json, statistics, sys
out, rounds = sys.argv[1], int(sys.argv[2])
names = ("motor_left", "motor_right", "sensor_fusion")
rows = {"off": [], "on": []}
print(f"{'run':8} " + " ".join(f"{n + ' p50/p99/max us':>30}" for n in names))
for i in range(1, rounds + 1):
    for mode in ("off", "on"):
        d = json.load(open(f"{out}/{mode}-{i}.json"))
        comps = {c["name"]: c for c in d["components"] if c["kind"] == "component"}
        cells, p99s = [], []
        for n in names:
            lat = comps[n]["timing"]["latency_ns"]
            cells.append(f"{lat['p50'] / 1e3:8.1f} {lat['p99'] / 1e3:8.1f} {lat['max'] / 1e3:9.1f}")
            if n.startswith("motor"):
                p99s.append(lat["p99"] / 1e3)
        rows[mode].append(max(p99s))
        print(f"{mode + '-' + str(i):8} " + " ".join(f"{c:>30}" for c in cells))
off = statistics.median(rows["off"])
on = statistics.median(rows["on"])
spread = lambda v: (max(v) - min(v)) / statistics.median(v) if statistics.median(v) else 0
print(f"motors' p99 (worse of the two), median of {rounds} rounds: off {off:.1f} us, on {on:.1f} us "
      f"(spread off {spread(rows['off']):.0%}, on {spread(rows['on']):.0%})")
print(f"RESULT off_p99_us={off:.1f} on_p99_us={on:.1f} ratio={on / off if off else 0:.3f}")
PY
