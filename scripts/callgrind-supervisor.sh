#!/usr/bin/env bash
# Instructions per message of the supervisor's drain, as counted by callgrind: repeatable to the
# instruction, unlike time on a shared machine (docs/design/performance-history.md, "Supervisor
# scale"). For comparing two builds of a change to the supervisor or the aggregator.
#
#   scripts/callgrind-supervisor.sh BENCH_BINARY [COMPONENTS] [PER_PORT]
#
#   BENCH_BINARY  vigil_bench_supervisor_throughput, built -O2 [-g] -DNDEBUG (benches/run's
#                 build, or build/release)
#   COMPONENTS    the row's components: 1, 100, 1000 or 10000 (default 100: 10,000 runs for
#                 minutes under callgrind)
#   PER_PORT      the row's messages per port and drain: 10 or 256 (default 10)
#
# Prints the instructions per message drained of what the benchmark times: `DrainLoop::step()`
# (inclusive, without the first step's joins) and the aggregator's final `catch_up()`; and of
# that, the statistics' catch-up (`take_pending_*`, wherever it is called from). Every step of the run counts, the warm-up's too: compare builds, not these
# figures with the benchmark's time. A CPU callgrind does not emulate (AVX-512) is not what the
# program chooses under it: the catch-up copy is the one CPUID gives inside valgrind. Needs
# valgrind (scripts/setup.sh).
set -euo pipefail
usage="usage: $0 BENCH_BINARY [COMPONENTS] [PER_PORT]"
bin=${1:?$usage}
components=${2:-100}
per_port=${3:-10}
[[ -x $bin ]] || { echo "$0: '$bin' is not an executable" >&2; exit 2; }
[[ $components =~ ^(1|100|1000|10000)$ ]] ||
  { echo "$0: COMPONENTS '$components' is not a row of the benchmark (1, 100, 1000, 10000)" >&2; exit 2; }
[[ $per_port =~ ^(10|256)$ ]] ||
  { echo "$0: PER_PORT '$per_port' is not a row of the benchmark (10, 256)" >&2; exit 2; }
command -v valgrind >/dev/null || { echo "$0: valgrind is missing (scripts/setup.sh)" >&2; exit 2; }
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
filter="^supervisor/throughput/components:$components/per_port:$per_port/"
valgrind --tool=callgrind --callgrind-out-file="$out/cg.out" "$bin" --benchmark_filter="$filter" \
  --benchmark_min_time=0.1 >"$out/log" 2>&1 || { tail -20 "$out/log" >&2; exit 1; }
grep -q "^supervisor/throughput/components:$components/per_port:$per_port/" "$out/log" ||
  { echo "$0: no row matched $filter" >&2; tail -5 "$out/log" >&2; exit 1; }
callgrind_annotate --inclusive=yes --tree=caller "$out/cg.out" >"$out/tree.txt" 2>/dev/null
python3 - "$out/tree.txt" "$components" "$per_port" <<'PY'
import re
import sys

lines = open(sys.argv[1]).read().splitlines()
components, per_port = int(sys.argv[2]), int(sys.argv[3])
fills = step = joins = catch_up = final = None


def inclusive(i):
    return int(lines[i].split()[0].replace(",", ""))


for i, line in enumerate(lines):
    if not line.lstrip().startswith(tuple("0123456789")) or "*" not in line:
        continue
    # A function's own line ("N (P%)  *  file:function"); its callers are the lines above it.
    if "Components::fill" in line and fills is None:
        m = re.search(r"\(([\d,]+)x\)", lines[i - 1])
        fills = int(m.group(1).replace(",", "")) if m else None
    elif re.search(r"DrainLoop<.*>::step\(\)", line) and step is None:
        step = inclusive(i)
    elif "ComponentAggregator::on_join" in line and joins is None:
        joins = inclusive(i)
    elif re.search(r"ComponentAggregator::catch_up\(\)", line) and final is None:
        final = inclusive(i)  # the benchmark's own, after the steps: on its clock too
    elif re.search(r"take_pending_(bits|base)\b", line):
        catch_up = (catch_up or 0) + inclusive(i)
if fills is None or step is None:
    sys.exit("callgrind-supervisor.sh: the profile has no Components::fill or DrainLoop::step()")
messages = fills * components * per_port
total = step - (joins or 0) + (final or 0)
print(f"components:{components}/per_port:{per_port}: {messages} messages; "
      f"{total / messages:.1f} Ir/msg (steps without the joins, and the final catch-up); "
      f"of which the statistics' catch-up {(catch_up or 0) / messages:.1f}")
PY
