#!/usr/bin/env bash
# benches/support/cpu-use.sh, the busy-machine check of benches/run: it refuses bad windows by
# name, sees CPUs kept busy by other processes, and, unlike the load average, does not carry a
# burst of load that ended before its window (benches/run's own build) into what it reports.
#
#   tests/benches/cpu_use_test.sh PATH/TO/cpu-use.sh
set -euo pipefail
tool=${1:?usage: $0 PATH/TO/cpu-use.sh}
n=$(nproc)
fail() {
  echo "FAIL: $*" >&2
  exit 1
}
ge() { awk -v a="$1" -v b="$2" 'BEGIN { exit !(a >= b) }'; }
err=$(mktemp)
hogs=()
trap 'kill "${hogs[@]}" 2> /dev/null || true; rm -f "$err"' EXIT

# A bad window: exit status 2 and a message that quotes it; nothing on standard output.
for bad in 0 0.0 -1 abc 1s; do
  set +e
  out=$("$tool" "$bad" 2> "$err")
  rc=$?
  set -e
  [[ $rc == 2 ]] || fail "window '$bad': exit status $rc, expected 2"
  grep -qF "'$bad'" "$err" || fail "window '$bad': the message does not quote it: $(cat "$err")"
  [[ -z $out ]] || fail "window '$bad': printed '$out'"
done

# The format: "<busy CPUs> <CPUs>", within 0 .. CPUs.
read -r busy cpus < <("$tool" 1)
[[ $cpus == "$n" ]] || fail "reported $cpus CPUs, nproc says $n"
[[ $busy =~ ^[0-9]+[.][0-9]{2}$ ]] || fail "busy CPUs '$busy' is not a decimal"
ge "$n" "$busy" || fail "busy CPUs $busy above the $n CPUs"

# The rest needs CPUs to spare: on a machine other work keeps busy (a build beside the suite),
# spinning processes add nothing it can see. Skipped then, saying so (CTest: exit status 77).
if ! ge "$(awk -v n="$n" 'BEGIN { print 0.25 * n }')" "$busy"; then
  echo "skipped: $busy of $n CPUs already busy with other work; the rest needs a quieter machine"
  exit 77
fi

# One spinning process per CPU: nearly every CPU is seen busy.
for ((i = 0; i < n; ++i)); do
  (while :; do :; done) &
  hogs+=($!)
done
read -r loaded _ < <("$tool" 2)
kill "${hogs[@]}"
wait "${hogs[@]}" 2> /dev/null || true
hogs=()
ge "$loaded" "$(awk -v n="$n" 'BEGIN { print 0.75 * n }')" ||
  fail "with $n spinning processes only $loaded of $n CPUs were seen busy"

# Right after they stopped the window sees them gone (the 1-minute load average would still
# count them). At least half the CPUs fewer: robust to a steady load of other tests.
read -r after _ < <("$tool" 2)
ge "$(awk -v l="$loaded" -v n="$n" 'BEGIN { print l - 0.5 * n }')" "$after" ||
  fail "after the spinning processes stopped, $after of $n CPUs busy (with them: $loaded)"
echo "cpu-use.sh: idle $busy, loaded $loaded, after $after of $n CPUs"
