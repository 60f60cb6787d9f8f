#!/usr/bin/env bash
# Sensor and bus faults end to end on a CAN interface, as a client sees them: the simulated F/T
# sensor (stepcal-ftsim, a fixed wrench without noise) on IFACE, the runtime daemon reading it
# (stepcal-runtime --sensor can:IFACE) and a client (stepcal-client) sending the same forward
# request at a steady rate over LCM, recording per reply when it left and came back, its status
# and the age of the live wrench it used. One fault at a time, each for a few seconds, healthy
# seconds between them:
#   restart      the sensor is killed and started again with another calibration (its matrix
#                ×1.25: read with the old one, the wrench would be 20 % too small)
#   stall        it stops answering, longer than the daemon's wrench age limit
#   bus-off      CAN error frame bus-off, later restarted (the sensor silent meanwhile)
#   critical     its readings carry critical status bits (0x8002: DAC/ADC too high, any error:
#                what a saturated gauge reports)
#   link-down    ip link set IFACE down, then up
#   flood        foreign frames as fast as cangen sends them (ids the kernel filter drops)
# Fails unless, for every fault: during it each reply is STALE_WRENCH, or OK on a wrench the
# sensor sent before the fault began (no reading taken during a sensor fault is ever used; a
# flood is no sensor fault, its readings count), and some reply is STALE_WRENCH (flood excepted);
# after it a reply is OK on a fresh wrench within 30 s (a liveness bound, not a performance one)
# without restarting the daemon. Over the whole run: no OK reply on a wrench older than the
# limit when the request left, every OK reply predicts the same position (the same wrench, so the
# right calibration), and the daemon is alive at the end and exits 0 on SIGTERM. Prints the table
# fault → statuses during it → time from its end to the first fresh OK (docs/can-sensor.md).
#
# Usage: tests/system/can_faults.sh MODEL OUT
#   MODEL  a model file (stepcal calibrate --out)
#   OUT    folder for the replies (client.json), the fault times (faults.json) and the logs
# Needs IFACE up (tests/system/vcan_run.sh provides one), root for ip link, cangen (can-utils), jq and
# UDP multicast on the loopback. Environment: STEPCAL_BIN_DIR, STEPCAL_CAN_IFACE, LCM_URL as for
# can_e2e.sh. Under the emulated VM (STEPCAL_IN_VCAN_VM=1) programs run 100 to 400 times slower:
# there 250 Hz polls, a 1 s age limit, a 100 ms budget and 10 requests/s, else 1000 Hz, 200 ms,
# 200 µs and 50/s; faults last 3 s either way.
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
if [[ $# -ne 2 ]]; then
  sed -n '2,/^set -e/{/^set -e/d;s/^# \{0,1\}//;p}' "$0" >&2
  exit 2
fi
model=$(realpath "$1")
out=$2
mkdir -p "$out"
out=$(realpath "$out")
source "$root/tests/system/can_lib.sh"
if [[ ${STEPCAL_IN_VCAN_VM:-0} == 1 ]]; then
  rate_hz=250 max_age_ms=1000 budget_us=100000 request_hz=10
else
  rate_hz=1000 max_age_ms=200 budget_us=200 request_hz=50
fi
fault_s=3 healthy_s=3
for tool in jq cangen ip; do
  command -v "$tool" >/dev/null || { echo "can_faults: needs $tool (jq, can-utils, iproute2)" >&2; exit 2; }
done
[[ -f $model ]] || { echo "can_faults: $model: no such model file" >&2; exit 2; }

wrench=(0 0 -300 5 -8 2)          # N, N·m on the sensor
joints=(0 0 0 0 28.64788975654116 0)  # deg (0.5 rad): OK with this wrench (inside the GPR's domain)
sensor=("$bin/stepcal-ftsim" --iface "$iface" --wrench "${wrench[@]}" --force-sigma-n 0
        --moment-sigma-nm 0)
: >"$out/faults.txt"
fault() { echo "$1 $2 $3 $4" >>"$out/faults.txt"; }  # name kind start end (Unix s)
# The Unix time stepcal-ftsim logged for an event (its log line "… EVENT at T s (unix U)").
logged() { sed -n "s/^stepcal-ftsim: $2 .*(unix \([0-9.]*\)).*/\1/p" "$1" | head -1; }

"${sensor[@]}" --json >"$out/ftsim-1.json" 2>"$out/ftsim-1.log" &
sensor_pid=$!
pids+=("$sensor_pid")
sleep 0.2  # the sensor answers from its first frame on; the daemon reads it at start-up
can_start_daemon "$model" "$out/daemon.log" "$rate_hz" "$max_age_ms" "$budget_us"
can_wait_ok can_faults "$out"/*.log
echo "settings: $rate_hz Hz sensor polls, max wrench age $max_age_ms ms, budget $budget_us us," \
  "$request_hz requests/s, faults of $fault_s s"

# The second sensor's own schedule (from its start): stall, bus-off, critical status; then the
# script's link-down and flood (ip link set down alone took 10 to 30 s in the VM). The client
# sends until it is stopped (at most 10 min).
stall_at=$healthy_s
bus_off_at=$((stall_at + fault_s + healthy_s))
critical_at=$((bus_off_at + fault_s + healthy_s))
schedule_s=$((critical_at + fault_s + healthy_s))
"$bin/stepcal-client" --lcm-url "$url" --forward "${joints[@]}" --count $((request_hz * 600)) \
  --rate "$request_hz" --timeout-ms 3000 --json >"$out/client.json" 2>"$out/client.log" &
client_pid=$!
pids+=("$client_pid")
sleep "$healthy_s"

# A fault lasts from when it took effect to when its end was asked for (a process start or exit
# takes a while in the VM): from the sensor's exit, from the link down to the command to bring it
# up; so the recovery time includes ip's run.
kill -TERM "$sensor_pid"
wait "$sensor_pid" || true
start=$EPOCHREALTIME
sleep "$fault_s"
"${sensor[@]}" --calibration-gain 1.25 --stall-at-s "$stall_at" --stall-for-s "$fault_s" \
  --bus-off-at-s "$bus_off_at" --bus-off-for-s "$fault_s" --status-word 0x8002 \
  --faults-at-s "$critical_at" --faults-for-s "$fault_s" --json >"$out/ftsim-2.json" 2>"$out/ftsim-2.log" &
pids+=($!)
until grep -q "sensor base id" "$out/ftsim-2.log"; do sleep 0.05; done
sensor_start=$(logged "$out/ftsim-2.log" "sensor base id")
fault restart sensor "$start" "$sensor_start"
sleep "$(jq -n "$sensor_start + $schedule_s - ($EPOCHREALTIME | tonumber) | [., 0] | max")"
fault stall sensor "$(logged "$out/ftsim-2.log" stalled)" "$(logged "$out/ftsim-2.log" "answering again")"
fault bus-off sensor "$(logged "$out/ftsim-2.log" bus-off)" "$(logged "$out/ftsim-2.log" "bus restarted")"
fault critical sensor "$(logged "$out/ftsim-2.log" "reading faults on")" \
  "$(logged "$out/ftsim-2.log" "reading faults off")"

ip link set "$iface" down
start=$EPOCHREALTIME
sleep "$fault_s"
fault link-down sensor "$start" "$EPOCHREALTIME"
ip link set "$iface" up
sleep "$healthy_s"

start=$EPOCHREALTIME
cangen "$iface" -g 0 -i -I 123 -L 8 -D r 2>"$out/cangen.log" &
flood_pid=$!
sleep "$fault_s"
kill -TERM "$flood_pid"
wait "$flood_pid" || true
fault flood bus "$start" "$EPOCHREALTIME"
sleep "$healthy_s"

kill -TERM "$client_pid"
# Exit status 3: requests not answered OK during the faults, what this test provokes and counts.
wait "$client_pid" || [[ $? -eq 3 ]] || { echo "can_faults: the client failed" >&2; cat "$out/client.log" >&2; exit 1; }
kill -0 "$daemon_pid" 2>/dev/null || { echo "can_faults: FAILED: the daemon died" >&2; cat "$out/daemon.log" >&2; exit 1; }
kill -TERM "$daemon_pid"
daemon_status=0
wait "$daemon_pid" || daemon_status=$?
echo "daemon alive after every fault; exit status on SIGTERM: $daemon_status"

jq -R -s '[split("\n")[] | select(length > 0) | split(" ") |
           {name: .[0], kind: .[1], start: (.[2] | tonumber), end: (.[3] | tonumber)}]' \
  "$out/faults.txt" >"$out/faults.json"

# Per reply the wrench's stamp (Unix s) = reply arrival − its age; per fault the replies that
# arrived during it, and the first OK after it on a wrench stamped after its end. A reading counts
# as the fault's from 20 ms after its logged start: the answer in flight when the simulator logs
# it arrives up to a poll later (stamped 0.7 ms after the logged stall in one run).
analysis='
  ($c[0].rows | map(select(.status != null) |
     . + {stamp: (if .wrench_age_ms then .received_unix_s - .wrench_age_ms / 1000 else null end)})) as $r |
  ($r | map(select(.status == "OK")) | first | .predicted_position_m) as $p0 |
  [$f[0][] | . as $fault |
    ($r | map(select(.received_unix_s >= $fault.start and .received_unix_s <= $fault.end))) as $during |
    ($r | map(select(.received_unix_s > $fault.end and .status == "OK" and .stamp > $fault.end)) | first) as $back |
    $fault + {
      replies: ($during | length),
      statuses: ($during | group_by(.status) | map({(.[0].status): length}) | add // {}),
      ok_on_fault_readings: ($during | map(select(.status == "OK" and .stamp >= $fault.start + 0.02)) | length),
      recovery_s: (if $back then $back.received_unix_s - $fault.end else null end)}] as $faults |
  {faults: $faults,
   lost: $c[0].lost,
   oldest_ok_wrench_ms: ($r | map(select(.status == "OK") | (.sent_unix_s - .stamp) * 1000) | max),
   position_spread_um: ($r | map(select(.status == "OK") | .predicted_position_m |
                          [range(3) as $i | (.[$i] - $p0[$i]) | fabs] | max) | max * 1e6)}'
jq -n --slurpfile c "$out/client.json" --slurpfile f "$out/faults.json" "$analysis" >"$out/summary.json"
jq -r '
  def r2: . * 100 | round / 100;
  (.faults[] | "\(.name): \(.end - .start | r2) s, \(.replies) replies during it \(.statuses | tostring), OK on readings from the fault: \(.ok_on_fault_readings), first fresh OK \(if .recovery_s then "\(.recovery_s | r2) s" else "never" end) after it"),
  "replies lost: \(.lost); oldest wrench of an OK reply when its request left: \(.oldest_ok_wrench_ms | r2) ms; OK positions within \(.position_spread_um * 1000 | round / 1000) um"' \
  "$out/summary.json"
echo "results: $out"

jq -e --argjson max_age_ms "$max_age_ms" --argjson status "$daemon_status" '
  $status == 0 and
  (.faults | length) == 6 and
  all(.faults[]; .ok_on_fault_readings == 0 or .kind == "bus") and
  all(.faults[]; .kind == "bus" or (.statuses.STALE_WRENCH // 0) > 0) and
  all(.faults[]; .recovery_s != null and .recovery_s <= 30) and
  .oldest_ok_wrench_ms <= $max_age_ms and
  .position_spread_um <= 1' "$out/summary.json" >/dev/null || {
  echo "can_faults: FAILED: a fault answered wrongly or not recovered from (see above)" >&2
  exit 1
}
echo "can_faults: OK"
