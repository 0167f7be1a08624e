#!/usr/bin/env bash
# Wake-up latency of the demo's 1 kHz and 500 Hz SCHED_FIFO components with health supervision on
# and off, in one run (issue 45, "Cost, measured").
#
#   benches/health/demo_on_off.sh [-b path/to/vigil] [-r rounds] [-D seconds] [-o dir]
#
# "on" is the built-in demo deployment (`vigil demo --print-config`: its `health:` section
# supervises four supervisions and the gripper, logger, encoder and telemetry pass checkpoints);
# "off" is the same file without the `health:` section (the checkpoints are still passed and
# drained, nothing judges them). Rounds alternate off, on, off, on... so that drift in the
# machine's load falls on both. Each run writes its final JSON; the healthy FIFO components'
# (motor_left, motor_right: 1 kHz, priority 80; sensor_fusion: 500 Hz, priority 70) latency
# p50/p99/max are printed per run, then the median over the rounds of each, and the ratio on/off.
# The last line is machine-readable:
#   RESULT off_p99_us=.. on_p99_us=.. ratio=..   (medians of the motors' p99 over the rounds)
# Use a Release build (build/release/apps/vigil/vigil): a dev build measures the assertions.
set -euo pipefail

vigil=build/release/apps/vigil/vigil
rounds=5
duration=8
out=""
while getopts "b:r:D:o:" opt; do
  case $opt in
    b) vigil=$OPTARG ;;
    r) rounds=$OPTARG ;;
    D) duration=$OPTARG ;;
    o) out=$OPTARG ;;
    *) sed -n '2,20p' "$0"; exit 2 ;;
  esac
done
[[ -x $vigil ]] || { echo "demo_on_off.sh: $vigil is missing (cmake --preset release &&" \
                          "cmake --build build/release --target vigil_cli)" >&2; exit 1; }
if [[ -z $out ]]; then
  out=$(mktemp -d)
  trap 'rm -rf "$out"' EXIT
fi
mkdir -p "$out"

"$vigil" demo --print-config > "$out/on.yaml"
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

for ((i = 1; i <= rounds; ++i)); do
  for mode in off on; do
    "$vigil" demo --config "$out/$mode.yaml" --duration "$duration" --no-live \
      --json "$out/$mode-$i.json" > "$out/$mode-$i.log" 2>&1 || true
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
