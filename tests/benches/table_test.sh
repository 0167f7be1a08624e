#!/usr/bin/env bash
# benches/support/table.awk, the reader behind benches/run's table: which run becomes the row,
# the verdict against each kind of goal, and numbers that never read on the wrong side of their
# goal (a ratio of 1.2041 against "<= 1.2" must not show as 1.20 next to FAIL).
#
#   tests/benches/table_test.sh PATH/TO/table.awk
set -euo pipefail
awk_file=${1:?usage: $0 PATH/TO/table.awk}
json=$(mktemp)
trap 'rm -f "$json"' EXIT
fail() {
  echo "FAIL: $*" >&2
  exit 1
}

# One benchmark object as Google Benchmark pretty-prints it: "name" then "key": value lines.
bench() {  # name family instance run_type aggregate_name repetitions key=value...
  local name=$1 family=$2 instance=$3 type=$4 agg=$5 reps=$6
  shift 6
  printf '    {\n      "name": "%s",\n      "family_index": %s,\n' "$name" "$family"
  printf '      "per_family_instance_index": %s,\n      "run_name": "%s",\n' "$instance" "${name%_median}"
  printf '      "run_type": "%s",\n      "repetitions": %s,\n' "$type" "$reps"
  [[ -n $agg ]] && printf '      "aggregate_name": "%s",\n' "$agg"
  local kv
  for kv in "$@"; do
    case ${kv#*=} in
      *[!0-9.e+-]*) printf '      "%s": "%s",\n' "${kv%%=*}" "${kv#*=}" ;;
      *) printf '      "%s": %s,\n' "${kv%%=*}" "${kv#*=}" ;;
    esac
  done
  printf '      "time_unit": "ns"\n    }'
}
{
  printf '{\n  "context": {\n    "num_cpus": 2\n  },\n  "benchmarks": [\n'
  # A mean aggregate: never a row (only medians are).
  bench ratio_over/manual_time_mean 0 0 aggregate mean 9 ratio=1.5 goal_ratio_max=1.2 real_time=10
  printf ',\n'
  # Ratio goals: just above (1.2041 -> 1.204 FAIL), just below (1.196 -> 1.20 PASS), far.
  bench ratio_over/manual_time_median 0 0 aggregate median 9 ratio=1.2041 goal_ratio_max=1.2 real_time=61.5 floor=51.1
  printf ',\n'
  bench ratio_under/manual_time_median 0 1 aggregate median 9 ratio=1.196 goal_ratio_max=1.2 real_time=60 floor=50.2
  printf ',\n'
  bench ratio_far/manual_time_median 0 2 aggregate median 9 ratio=0.8912 goal_ratio_max=1 real_time=45
  printf ',\n'
  bench ratio_equal/manual_time_median 0 3 aggregate median 9 ratio=1.2 goal_ratio_max=1.2 real_time=45
  printf ',\n'
  bench ratio_min_under/manual_time_median 0 4 aggregate median 9 ratio=1.4996 goal_ratio_min=1.5 real_time=45
  printf ',\n'
  # Value goals: 5.004 % against "<= 5" is 5.004 FAIL (not "5"); 39.996 M against ">= 40M" is
  # 39.996M FAIL (not "40M"); 40.21 M is PASS with the usual digits.
  bench share/iterations:1/manual_time_median 1 0 aggregate median 9 "value=5.004" goal_value_max=5 "label=% of a core" ratio=0.5
  printf ',\n'
  bench rate_under/manual_time_median 1 1 aggregate median 9 value=39996000 goal_value_min=40000000 label=msg/s
  printf ',\n'
  bench rate_over/manual_time_median 1 2 aggregate median 9 value=40210000 goal_value_min=40000000 label=msg/s
  printf ',\n'
  # No goal: the usual digits; one repetition: the run itself is the row.
  bench plain 2 0 iteration "" 1 value=72633 label=bytes
  printf ',\n'
  # An iteration of a repeated benchmark: never a row.
  bench repeated 2 1 iteration "" 9 value=1
  printf ',\n'
  bench broken 3 0 iteration "" 1 error_occurred=true "error_message=CAN log not found"
  printf '\n  ]\n}\n'
} > "$json"

rows=$(awk -v section=S -f "$awk_file" "$json")
expect() {  # name expected-row-without-section-and-order
  local got
  got=$(awk -F'|' -v n="$1" '$2 == n { print $3 "|" $4 "|" $5 "|" $6 "|" $7 "|" $8 }' <<< "$rows")
  [[ $got == "$2" ]] || fail "$1: got '$got', expected '$2' (all rows:
$rows)"
}
expect ratio_over "61.5|ns|51.1|1.204|ratio <= 1.2|FAIL"
expect ratio_under "60.0|ns|50.2|1.20|ratio <= 1.2|PASS"
expect ratio_far "45.0|ns|-|0.89|ratio <= 1|PASS"
expect ratio_equal "45.0|ns|-|1.20|ratio <= 1.2|PASS"
expect ratio_min_under "45.0|ns|-|1.4996|ratio >= 1.5|FAIL"
expect share "5.004|% of a core|-|0.50|<= 5|FAIL"
expect rate_under "39.996M|msg/s|-|-|>= 40M|FAIL"
expect rate_over "40.21M|msg/s|-|-|>= 40M|PASS"
expect plain "72.6k|bytes|-|-|-|-"
expect broken "CAN log not found|-|-|-|-|n/a"
n=$(wc -l <<< "$rows")
[[ $n == 10 ]] || fail "$n rows, expected 10 (the mean aggregate and a repeated run's iteration are none):
$rows"
# Rows carry the registration order (family, instance): benches/run sorts on it.
[[ $(awk -F'|' '$2 == "rate_under" { print $9 }' <<< "$rows") == 00010001 ]] || fail "order of rate_under"
echo "ok: $n rows"
