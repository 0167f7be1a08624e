#!/usr/bin/env bash
# How many CPUs the machine keeps busy, measured over a window in which the caller does nothing:
# the time every CPU spent neither idle nor waiting for I/O (user, nice, system, interrupts, and
# steal: time the hypervisor gave to another guest), from /proc/stat at both ends of the window.
#
#   benches/support/cpu-use.sh [SECONDS]     (default 3; a decimal such as 0.5 is accepted)
#
# Prints one line: "<busy CPUs> <CPUs>", e.g. "0.04 2": 0.04 of the 2 CPUs were busy. The caller
# sleeps meanwhile, so what is counted is other processes' (and the host's) use of the CPUs.
# Unlike the load average, a 1-minute mean, this says nothing of what ran before the window: it
# is what benches/run uses right after its own build, which would leave the load average high
# for a minute on a quiet machine. Exit status 2 with a message for a bad argument or an
# unreadable /proc/stat.
set -euo pipefail

window=${1:-3}
if ! [[ $window =~ ^[0-9]+([.][0-9]+)?$ ]] || [[ $window =~ ^0+([.]0+)?$ ]]; then
  echo "cpu-use.sh: SECONDS must be a positive number, got '$window'" >&2
  exit 2
fi

# "<busy ticks> <all ticks>" of the aggregate cpu line.
ticks() {
  local line
  line=$(grep -m1 '^cpu ' /proc/stat 2> /dev/null) || {
    echo "cpu-use.sh: cannot read the aggregate cpu line of /proc/stat" >&2
    exit 2
  }
  # cpu user nice system idle iowait irq softirq steal [guest guest_nice: already in user/nice]
  awk '{ busy = $2 + $3 + $4 + $7 + $8 + $9; print busy, busy + $5 + $6 }' <<< "$line"
}

ncpu=$(nproc)
# Assignments, not process substitutions: ticks' exit status 2 ends this script with it.
t0=$(ticks)
sleep "$window"
t1=$(ticks)
read -r busy0 all0 <<< "$t0"
read -r busy1 all1 <<< "$t1"
awk -v b="$((busy1 - busy0))" -v a="$((all1 - all0))" -v n="$ncpu" \
  'BEGIN { printf "%.2f %d\n", (a > 0 ? b / a : 0) * n, n }'
