#!/usr/bin/env bash
# `vigil demo --ros2` seen from a separate subscriber process: the Cyclone DDS listener of the
# suite (tests/export/ros2_listener.cpp) subscribes to rt/diagnostics in a random domain, given
# to the demo through ROS_DOMAIN_ID, both on loopback with unicast discovery (CYCLONEDDS_URI).
# It checks the demo's start-up line, a monitor cycle's array (every component of the demo, by
# its ROS 2 name), an event's sample (the faulty encoder's status, published at once), and that
# a demo without --ros2 maps no DDS library; and that it announces its node /vigil on
# ros_discovery_info (Jazzy's layout: ROS_DISTRO is unset here) with the /diagnostics writer.
#
#   ros2_demo_test.sh VIGIL LISTENER
set -euo pipefail
vigil=$1
listener=$2
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

domain=$((20 + RANDOM % 180))
export ROS_DOMAIN_ID=$domain
unset ROS_DISTRO
export CYCLONEDDS_URI='<CycloneDDS><Domain id="any"><General><Interfaces><NetworkInterface name="lo"/></Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>20</MaxAutoParticipantIndex><Peers><Peer address="127.0.0.1"/></Peers></Discovery></Domain></CycloneDDS>'

fail() {
  echo "FAIL: $*"
  echo "--- demo:"; cat "$out/demo.out" || true
  echo "--- listener (stderr):"; cat "$out/listener.err" || true
  echo "--- samples:"; cut -c1-300 "$out/samples" || true
  exit 1
}

# Every sample until 8 monitor cycles' arrays (10 statuses or more) arrived, within 40 s: the
# demo runs 14 s (a cycle a second, the events in between); and ros_discovery_info (16-byte gids).
"$listener" "$domain" 8 40 10 16 > "$out/samples" 2> "$out/listener.err" &
listener_pid=$!
"$vigil" demo --ros2 --no-live --duration 14 > "$out/demo.out" 2>&1 &
demo_pid=$!
wait "$listener_pid" || fail "the listener did not receive 8 monitor cycles"
ros2_locked=$(awk '/^VmLck:/ {print $2}' "/proc/$demo_pid/status" 2>/dev/null || echo 0)
wait "$demo_pid" || fail "the demo failed"

grep -q "ROS 2: /diagnostics (DDS topic rt/diagnostics) in domain $domain, node /vigil" \
  "$out/demo.out" || fail "no start-up line naming the domain and the node"
for name in motor_left motor_right sensor_fusion planner encoder; do
  grep -q "\"name\":\"vigil: $name\"" "$out/samples" || fail "no status named 'vigil: $name'"
done
grep -q '"hardware_id":"tid [0-9]* cpu [0-9a-z]*"' "$out/samples" || fail "no component hardware_id"
grep -q '"key":"event","value":"exception"' "$out/samples" ||
  fail "no event's sample (the encoder's exception)"
grep -q '"name":"vigil: encoder","message":"ERROR encoder: exception' "$out/samples" ||
  fail "the encoder's exception is not its status's message"
# The node: /vigil, whose one writer is the /diagnostics writer the listener received from, in
# that writer's participant (graph ids as rmw_cyclonedds_cpp derives them from DDS discovery).
node=$(grep '"ros_discovery_info"' "$out/samples") || fail "no ros_discovery_info sample"
writer=$(sed -E 's/.*"publisher":\{"gid":"([0-9a-f]+)".*/\1/' <<< "$node")
participant=$(sed -E 's/.*"participant_gid":"([0-9a-f]+)".*/\1/' <<< "$node")
expected="{\"ros_discovery_info\":{\"gid\":\"$participant\",\"nodes\":[{\"namespace\":\"/\",\"name\":\"vigil\",\"readers\":[],\"writers\":[\"$writer\"]}]}"
[[ ${#writer} == 32 && $node == "$expected"* ]] ||
  fail "ros_discovery_info does not name /vigil with the /diagnostics writer: $node"

# Without --ros2 no DDS library is mapped (the module is opened only by the output).
"$vigil" demo --no-live --duration 4 > "$out/plain.out" 2>&1 &
plain_pid=$!
sleep 3
if grep -q -E 'libddsc|libvigil_ros2' "/proc/$plain_pid/maps"; then
  fail "a demo without --ros2 maps a DDS library"
fi
plain_locked=$(awk '/^VmLck:/ {print $2}' "/proc/$plain_pid/status")
wait "$plain_pid" || fail "the plain demo failed"

# With memory locked, what DDS adds stays bounded (its libraries, small thread stacks: ~12 MiB);
# Cyclone's seven threads with glibc's default 8 MiB stacks added 56 MiB.
if grep -q "memory locked" "$out/plain.out" && ((plain_locked > 0 && ros2_locked > 0)); then
  ((ros2_locked - plain_locked < 24576)) ||
    fail "--ros2 locks $((ros2_locked - plain_locked)) kB more than without (limit 24576 kB)"
  echo "locked: $plain_locked kB without --ros2, $ros2_locked kB with it"
fi
echo "ok: $(wc -l < "$out/samples") samples in domain $domain"
