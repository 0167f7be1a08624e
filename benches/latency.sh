#!/usr/bin/env bash
# Wake-up latency of a vigil PeriodicActivity next to cyclictest (Debian package rt-tests), with
# the same priority, interval, CPU and duration, run one after the other (alternating when there
# are several rounds), and both distributions printed side by side.
#
#   benches/latency.sh [-D seconds] [-p priority] [-i interval_us] [-a cpu] [-h max_us]
#                      [-r rounds] [-b path/to/vigil_latency] [-k dir-to-keep-histograms]
#
# cyclictest runs as `cyclictest -m -p<prio> -i<interval> -a<cpu> -t1 -D<seconds> -q -h<max_us>`;
# vigil_latency (benches/latency/vigil_latency.cpp) prints the same histogram format: 1 us
# buckets, truncated, so one awk computes min, median, p99, p99.9 and max for both. Rounds are
# merged per tool. The last line is machine-readable for benches/run:
#   RESULT cyclictest_p99_us=.. vigil_p99_us=.. ratio=.. (ratio = vigil p99 / cyclictest p99)
# Needs root (or CAP_SYS_NICE and a memlock limit) for SCHED_FIFO and mlockall.
set -euo pipefail

duration=30
priority=80
interval=1000
cpu=1
max_us=10000
rounds=1
keep=""
here=$(cd "$(dirname "$0")" && pwd)
vigil_latency=""

while getopts "D:p:i:a:h:r:b:k:" opt; do
  case $opt in
    D) duration=$OPTARG ;;
    p) priority=$OPTARG ;;
    i) interval=$OPTARG ;;
    a) cpu=$OPTARG ;;
    h) max_us=$OPTARG ;;
    r) rounds=$OPTARG ;;
    b) vigil_latency=$OPTARG ;;
    k) keep=$OPTARG ;;
    *) sed -n '2,16p' "$0"; exit 2 ;;
  esac
done

if [[ -z $vigil_latency ]]; then
  for candidate in "$here/../build/bench/benches/vigil_latency" \
                   "$here/../build/release/benches/vigil_latency"; do
    if [[ -x $candidate ]]; then vigil_latency=$candidate; break; fi
  done
fi
if ! command -v cyclictest > /dev/null; then
  echo "latency.sh: cyclictest not found (apt-get install rt-tests)" >&2
  echo "RESULT not_available=cyclictest"
  exit 3
fi
if [[ -z $vigil_latency || ! -x $vigil_latency ]]; then
  echo "latency.sh: vigil_latency not found (build the benches, or pass -b)" >&2
  echo "RESULT not_available=vigil_latency"
  exit 3
fi
ncpu=$(nproc)
if (( cpu >= ncpu )); then cpu=$((ncpu - 1)); fi

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

echo "latency.sh: priority $priority, interval ${interval} us, CPU $cpu, ${duration} s x $rounds" \
     "round(s) per tool, histogram to ${max_us} us" >&2
for ((r = 1; r <= rounds; r++)); do
  echo "latency.sh: round $r: cyclictest" >&2
  cyclictest -m -p"$priority" -i"$interval" -a"$cpu" -t1 -D"$duration" -q -h"$max_us" \
    > "$work/cyclictest.$r.txt"
  echo "latency.sh: round $r: vigil" >&2
  "$vigil_latency" -p "$priority" -i "$interval" -a "$cpu" -D "$duration" -h "$max_us" \
    > "$work/vigil.$r.txt"
done
if [[ -n $keep ]]; then mkdir -p "$keep" && cp "$work"/*.txt "$keep"/; fi

# Reads histogram files ("bucket count" lines, "# Max Latencies:", "# Histogram Overflows:"),
# merges them, prints "samples min median p99 p99.9 max overflows" (us; ">N" past the histogram).
stats() {
  awk -v max_us="$max_us" '
    /^[0-9]+[ \t]+[0-9]+/ { h[$1 + 0] += $2; total += $2; next }
    /^# Max Latencies:/   { if ($4 + 0 > max) max = $4 + 0; next }
    /^# Histogram Overflows:/ { over += $4; total += $4; next }
    function pct(q,   need, c, b) {
      need = int(q * total); if (need < q * total) need++; if (need < 1) need = 1
      c = 0
      for (b = 0; b < max_us; b++) { c += h[b]; if (c >= need) return b }
      return ">" max_us
    }
    END {
      if (total == 0) { print "0 - - - - - 0"; exit }
      for (b = 0; b < max_us; b++) if (h[b] > 0) { min = b; break }
      if (b == max_us) min = ">" max_us
      printf "%d %s %s %s %s %d %d\n", total, min, pct(0.5), pct(0.99), pct(0.999), max, over
    }' "$@"
}

read -r c_n c_min c_med c_p99 c_p999 c_max c_over < <(stats "$work"/cyclictest.*.txt)
read -r v_n v_min v_med v_p99 v_p999 v_max v_over < <(stats "$work"/vigil.*.txt)

printf '%-22s %12s %12s\n' "wake-up latency (us)" "cyclictest" "vigil"
printf '%-22s %12s %12s\n' "samples" "$c_n" "$v_n"
printf '%-22s %12s %12s\n' "min" "$c_min" "$v_min"
printf '%-22s %12s %12s\n' "median" "$c_med" "$v_med"
printf '%-22s %12s %12s\n' "p99" "$c_p99" "$v_p99"
printf '%-22s %12s %12s\n' "p99.9" "$c_p999" "$v_p999"
printf '%-22s %12s %12s\n' "max" "$c_max" "$v_max"
printf '%-22s %12s %12s\n' "beyond histogram" "$c_over" "$v_over"

ratio=$(awk -v a="$v_p99" -v b="$c_p99" 'BEGIN {
  if (a ~ /^>/ || b ~ /^>/ || b + 0 == 0) { print "nan"; exit }
  printf "%.3f", a / b }')
echo "RESULT cyclictest_p99_us=$c_p99 vigil_p99_us=$v_p99 ratio=$ratio" \
     "cyclictest_median_us=$c_med vigil_median_us=$v_med samples=$c_n/$v_n"
