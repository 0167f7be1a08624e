#!/usr/bin/env bash
# Figures of fuzzing runs (for docs/design/reliability.md): per target, the executions, coverage
# (cov: edges, ft: features) and corpus size from libFuzzer's last status line, the CPU seconds
# used, and the inputs found (artifacts).
#   tests/fuzz/figures.sh WORKROOT
work="$1"
printf '%-12s %12s %7s %7s %7s %8s %s\n' target executions cov ft corpus cpu_s findings
for d in "$work"/*/; do
  t=$(basename "$d")
  log="$d/fuzz.log"
  [[ -f "$log" ]] || continue
  last=$(grep -E "^#[0-9]+" "$log" | tail -n 1)
  execs=$(grep -h "stat::number_of_executed_units" "$log" | awk '{s += $2} END {print s + 0}')
  [[ "$execs" == 0 ]] && execs=$(sed -E 's/^#([0-9]+).*/\1/' <<<"$last")
  cov=$(grep -oE "cov: [0-9]+" <<<"$last" | awk '{print $2}')
  ft=$(grep -oE "ft: [0-9]+" <<<"$last" | awk '{print $2}')
  corp=$(grep -oE "corp: [0-9]+" <<<"$last" | awk '{print $2}')
  used=$(grep -oE "[0-9]+ CPU seconds used" "$log" | tail -n 1 | awk '{print $1}')
  found=$(ls "$d/artifacts" 2>/dev/null | wc -l)
  printf '%-12s %12s %7s %7s %7s %8s %s\n' "$t" "$execs" "${cov:--}" "${ft:--}" "${corp:--}" "${used:--}" "$found"
done
