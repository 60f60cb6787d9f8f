#!/usr/bin/env bash
# End to end on a CAN interface: the simulated F/T sensor (stepcal-ftsim) on IFACE, the runtime
# daemon reading it (stepcal-runtime --sensor can:IFACE) and the client (stepcal-client) sending
# the campaign's validation rows as forward requests over LCM, with the payload moving through
# those poses. The same rows are sent twice: with their measured wrench (the offline figure: the
# daemon then computes exactly the trainer's validation) and with the live sensor. Checks that
# the live accuracy equals the offline one within the noise, that every request was answered OK,
# and reports the latencies.
#
# Usage: tools/can_e2e.sh CAMPAIGN MODEL [OUT]
#   CAMPAIGN  simulated campaign folder with truth.json (stepcal simulate)
#   MODEL     its model file (stepcal calibrate --out)
#   OUT       folder for the JSON results and logs (default: a temporary one)
# Needs a host with IFACE up (default vcan0; tools/vcan_run.sh provides one) and UDP multicast on
# the loopback (route 224.0.0.0/4 dev lo). Environment (STEPCAL_ and LCM_ names cross into the
# VM): STEPCAL_BIN_DIR (default build/bin), STEPCAL_CAN_IFACE (default vcan0), LCM_URL,
# STEPCAL_E2E_MODE (forward | inverse, default forward), STEPCAL_E2E_RATE_HZ (sensor polls),
# STEPCAL_E2E_SETTLE_MS (wait after the sensor felt each robot state),
# STEPCAL_E2E_MAX_WRENCH_AGE_MS and STEPCAL_E2E_BUDGET_US (the daemon's limits). Under the
# emulated VM (STEPCAL_IN_VCAN_VM=1) every program runs some 100 to 400 times slower, so the
# defaults there are 250 Hz polls, a 50 ms settle, a 500 ms age limit and a 100 ms budget (else
# 1000 Hz, 5 ms, 20 ms and 200 µs), and the absolute latencies are the emulator's, not the
# machine's.
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
if [[ $# -lt 2 || $# -gt 3 ]]; then
  sed -n '2,18p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 2
fi
campaign=$(realpath "$1")
model=$(realpath "$2")
out=${3:-$(mktemp -d /tmp/can_e2e.XXXXXX)}
mkdir -p "$out"
bin=$(realpath "${STEPCAL_BIN_DIR:-$root/build/bin}")
iface=${STEPCAL_CAN_IFACE:-vcan0}
url=${LCM_URL:-udpm://239.255.76.67:7667?ttl=0}
if [[ ${STEPCAL_IN_VCAN_VM:-0} == 1 ]]; then
  rate_hz=${STEPCAL_E2E_RATE_HZ:-250}
  settle_ms=${STEPCAL_E2E_SETTLE_MS:-50}
  max_age_ms=${STEPCAL_E2E_MAX_WRENCH_AGE_MS:-500}
  budget_us=${STEPCAL_E2E_BUDGET_US:-100000}
else
  rate_hz=${STEPCAL_E2E_RATE_HZ:-1000}
  settle_ms=${STEPCAL_E2E_SETTLE_MS:-5}
  max_age_ms=${STEPCAL_E2E_MAX_WRENCH_AGE_MS:-20}
  budget_us=${STEPCAL_E2E_BUDGET_US:-200}
fi
mode=${STEPCAL_E2E_MODE:-forward}
command -v jq >/dev/null || { echo "can_e2e: needs jq (apt-get install jq)" >&2; exit 2; }
[[ -f $campaign/truth.json ]] || { echo "can_e2e: $campaign/truth.json: not a simulated campaign" >&2; exit 2; }
[[ -f $model ]] || { echo "can_e2e: $model: no such model file" >&2; exit 2; }

pids=()
cleanup() {
  for pid in "${pids[@]}"; do kill -TERM "$pid" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null || true; done
}
trap cleanup EXIT

"$bin/stepcal-ftsim" --iface "$iface" --truth "$campaign/truth.json" --lcm-url "$url" --json \
  >"$out/ftsim.json" 2>"$out/ftsim.log" &
pids+=($!)
sleep 0.2  # the sensor answers from its first frame on; the daemon reads it at start-up
"$bin/stepcal-runtime" --model "$model" --lcm-url "$url" --sensor "can:$iface" \
  --sensor-rate-hz "$rate_hz" --max-wrench-age-ms "$max_age_ms" --budget-us "$budget_us" 2>"$out/daemon.log" &
pids+=($!)

# Ready when a forward request with the live wrench is answered OK.
for _ in $(seq 100); do
  if "$bin/stepcal-client" --lcm-url "$url" --forward 0 0 0 0 0.5 0 --timeout-ms 200 --json \
      2>/dev/null | jq -e '.status == "OK"' >/dev/null; then
    ready=1
    break
  fi
  sleep 0.1
done
if [[ -z ${ready:-} ]]; then
  echo "can_e2e: the daemon does not answer OK with the live sensor" >&2
  cat "$out"/*.log >&2
  exit 1
fi
grep -h "stepcal-runtime:" "$out/daemon.log" | head -1
echo "settings: $rate_hz Hz sensor polls, settle $settle_ms ms, max wrench age $max_age_ms ms, budget $budget_us us"

common=(--lcm-url "$url" --campaign "$campaign" --set validation --mode "$mode"
        --truth "$campaign/truth.json" --timeout-ms 1000 --json)
"$bin/stepcal-client" "${common[@]}" >"$out/offline.json"
"$bin/stepcal-client" "${common[@]}" --live-wrench --settle-ms "$settle_ms" >"$out/live.json"

jq -r -n --slurpfile off "$out/offline.json" --slurpfile live "$out/live.json" '
  def r4: . * 10000 | round / 10000;
  def r1: . * 10 | round / 10;
  def acc(a): "mean \(a.mean_position_mm | r4) mm, max \(a.max_position_mm | r4) mm, mean \(a.mean_orientation_deg | r4) deg";
  def lat(l): "p50 \(l.p50_us | r1) us, p99 \(l.p99_us | r1) us, max \(l.max_us | r1) us (\(l.samples))";
  ($off[0]) as $o | ($live[0]) as $l |
  "\($l.requests) \($l.mode) requests, validation rows of the campaign; robot states the sensor did not confirm: \($l.robot_states_not_applied)",
  "statuses: measured wrench \($o.statuses | tostring), live sensor \($l.statuses | tostring)",
  (if $l.mode == "forward" then
    "accuracy vs measured pose, measured wrench (offline figure): \(acc($o.accuracy))",
    "accuracy vs measured pose, live CAN wrench:                  \(acc($l.accuracy))",
    "accuracy vs twin truth,    measured wrench:                  \(acc($o.accuracy_truth))",
    "accuracy vs twin truth,    live CAN wrench:                  \(acc($l.accuracy_truth))"
   else
    "accuracy vs twin truth, measured wrench: \(acc($o.accuracy))",
    "accuracy vs twin truth, live CAN wrench: \(acc($l.accuracy))"
   end),
  "request to reply (live):  \(lat($l.round_trip_us))",
  "CAN frame to reply (live): \(lat($l.sensor_frame_to_reply_us))",
  "daemon compute (live):    \(lat($l.compute_us))"
'
echo "results: $out"

# Within the noise: every request answered OK, and the live mean position error within 10 % (or
# 2 µm) of the offline one: the live wrench differs from the measured one by the F/T noise only.
jq -e -n --slurpfile off "$out/offline.json" --slurpfile live "$out/live.json" '
  ($off[0]) as $o | ($live[0]) as $l |
  ($l.lost == 0) and ($o.lost == 0) and ($l.statuses == {"OK": $l.requests}) and
  ($l.robot_states_not_applied == 0) and
  ((($l.accuracy.mean_position_mm - $o.accuracy.mean_position_mm) | fabs)
     <= ([0.1 * $o.accuracy.mean_position_mm, 0.002] | max))' >/dev/null || {
  echo "can_e2e: FAILED: live accuracy or statuses differ from the offline run (see above)" >&2
  exit 1
}
echo "can_e2e: OK"
