#!/usr/bin/env bash
# Instructions per cycle of one per-cycle-overhead benchmark row and of its floor, as counted by
# callgrind (docs/design/performance-history.md, "The per-cycle path at the floor"). Repeatable
# to the instruction, unlike time on a shared machine.
#
#   scripts/callgrind-cycle.sh BENCH_BINARY FILTER [SUBJECT_FUNCTION]
#
#   BENCH_BINARY       vigil_bench_task_overhead, built -O2 [-g] -DNDEBUG (benches/run's build,
#                      or a Release build with -g for per-line annotation)
#   FILTER             a Google Benchmark filter selecting ONE row, e.g.
#                      '^task/overhead/detectors:none/iter'
#   SUBJECT_FUNCTION   the subject's cycle function (callgrind --toggle-collect pattern); default
#                      '*Subject*::cycle()'; use '*TscTaskSubject::cycle()' for the tsc_clock rows
#                      (their cycle() calls TaskSubject::cycle(), which would toggle collection off)
#
# One repetition is 3 warm-up batches + 50 timed batches of 200 cycles = 10,600 cycles of each side.
# A vDSO clock read counts ~21 instructions here: valgrind turns it into a system call it does
# not count. Needs valgrind (scripts/setup.sh).
set -euo pipefail
bin=${1:?usage: $0 BENCH_BINARY FILTER [SUBJECT_FUNCTION]}
filter=${2:?usage: $0 BENCH_BINARY FILTER [SUBJECT_FUNCTION]}
subject=${3:-'*Subject*::cycle()'}
cycles=10600
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
count() {  # pattern -> instructions collected
  VIGIL_BENCH_LTTNG=0 valgrind --tool=callgrind --callgrind-out-file="$out/cg.out" \
    --toggle-collect="$1" "$bin" --benchmark_filter="$filter" --benchmark_repetitions=1 \
    > "$out/log" 2>&1 || { tail -20 "$out/log" >&2; exit 1; }
  grep -o 'Collected : [0-9]*' "$out/log" | awk '{print $3}'
}
floor=$(count 'vigil::bench::Floor::cycle()')
subj=$(count "$subject")
awk -v f="$floor" -v s="$subj" -v n="$cycles" -v row="$filter" \
  'BEGIN { printf "%s: floor %.1f Ir/cycle, subject %.1f Ir/cycle\n", row, f / n, s / n }'
