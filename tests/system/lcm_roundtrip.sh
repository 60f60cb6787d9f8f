#!/usr/bin/env bash
# Round trips between stepcal-client and stepcal-runtime over real UDP multicast LCM, in a private
# network namespace (loopback only, nothing leaves the machine), against a raw LCM ping-pong of
# the same message size between two stepcal-client processes: the ratio is the daemon's cost.
#
# Usage (root): tests/system/lcm_roundtrip.sh MODEL [CAMPAIGN] [N]
#   MODEL      model file, e.g. out/demo-campaign/model.stepcal (stepcal demo)
#   CAMPAIGN   campaign whose validation rows become the requests (default: MODEL's folder)
#   N          requests and pings (default 100000)
# Environment: STEPCAL_BIN_DIR (default build/bin), LCM_URL (default
# udpm://239.255.76.67:7667?ttl=0), MODE (forward | inverse, default forward), REALTIME=1
# (daemon with --realtime), RATE_HZ (requests and pings on a fixed schedule at this rate; default
# one in flight at a time), TIMEOUT_MS (a reply later than this is lost, default 100), OUT
# (folder for the JSON results, default a temporary one), KEY_FILE (a cell key: the daemon and
# the requests' client with --key-file; the raw pings stay as they are).
# Exit status: 0, 1 when a request or ping got no reply, 2 usage, 77 skipped (no `unshare -n`).
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
if [[ $# -lt 1 || $# -gt 3 ]]; then
  sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 2
fi
model=$(realpath "$1")
campaign=$(realpath "${2:-$(dirname "$model")}")
count=${3:-100000}
bin=$(realpath "${STEPCAL_BIN_DIR:-$root/build/bin}")
url=${LCM_URL:-udpm://239.255.76.67:7667?ttl=0}
mode=${MODE:-forward}

if [[ -z ${STEPCAL_IN_NETNS:-} ]]; then
  if [[ $(id -u) -ne 0 ]] || ! unshare -n true 2>/dev/null; then
    echo "lcm_roundtrip: skipped: this machine does not permit a network namespace (unshare -n; needs root or CAP_SYS_ADMIN)"
    exit 77
  fi
  command -v jq >/dev/null || { echo "lcm_roundtrip: needs jq (apt-get install jq)" >&2; exit 2; }
  for f in "$bin/stepcal-runtime" "$bin/stepcal-client"; do
    [[ -x $f ]] || { echo "lcm_roundtrip: $f: not built (set STEPCAL_BIN_DIR)" >&2; exit 2; }
  done
  [[ -f $model ]] || { echo "lcm_roundtrip: $model: no such model file" >&2; exit 2; }
  STEPCAL_IN_NETNS=1 exec unshare -n "$0" "$model" "$campaign" "$count"
fi

ip link set lo up
ip route add 224.0.0.0/4 dev lo
out=${OUT:-$(mktemp -d /tmp/lcm_roundtrip.XXXXXX)}
mkdir -p "$out"
pids=()
cleanup() {
  for pid in "${pids[@]}"; do kill -TERM "$pid" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null || true; done
}
trap cleanup EXIT

key_args=()
[[ -n ${KEY_FILE:-} ]] && key_args=(--key-file "$(realpath "$KEY_FILE")")
daemon_args=(--model "$model" --lcm-url "$url" "${key_args[@]}")
[[ ${REALTIME:-0} == 1 ]] && daemon_args+=(--realtime)
"$bin/stepcal-runtime" "${daemon_args[@]}" 2>"$out/daemon.log" &
pids+=($!)
"$bin/stepcal-client" --echo --lcm-url "$url" 2>"$out/echo.log" &
pids+=($!)

# Ready when a request gets any reply (STALE_WRENCH, exit status 3: no live sensor here) and a
# ping a pong.
for _ in $(seq 50); do
  probe=0
  "$bin/stepcal-client" --lcm-url "$url" --forward 0 0 0 0 28.64788975654116 0 --timeout-ms 100 \
    "${key_args[@]}" >/dev/null 2>&1 || probe=$?
  if [[ $probe -eq 0 || $probe -eq 3 ]] &&
    "$bin/stepcal-client" --lcm-url "$url" --ping 1 --timeout-ms 100 >/dev/null 2>&1; then
    ready=1
    break
  fi
  sleep 0.1
done
[[ -n ${ready:-} ]] || { echo "lcm_roundtrip: daemon or echo not answering" >&2; cat "$out"/*.log >&2; exit 1; }

echo "$count raw pings (stepcal-client --ping ↔ --echo) on $url ..."
rate_args=(--timeout-ms "${TIMEOUT_MS:-100}")
[[ -n ${RATE_HZ:-} ]] && rate_args+=(--rate "$RATE_HZ")
# Exit status 3 (some pings or requests without a reply, or not OK): the table below counts them.
"$bin/stepcal-client" --lcm-url "$url" --ping "$count" "${rate_args[@]}" --json >"$out/ping.json" ||
  [[ $? -eq 3 ]]
echo "$count $mode requests (stepcal-client --campaign $campaign ↔ stepcal-runtime) ..."
request_args=(--lcm-url "$url" --campaign "$campaign" --mode "$mode" --count "$count" --json
  "${rate_args[@]}" "${key_args[@]}")
# Inverse answers are checked against the twin's truth when the campaign was simulated.
[[ $mode == inverse && -f $campaign/truth.json ]] && request_args+=(--truth "$campaign/truth.json")
"$bin/stepcal-client" "${request_args[@]}" >"$out/requests.json" || [[ $? -eq 3 ]]

jq -r -n --slurpfile ping "$out/ping.json" --slurpfile req "$out/requests.json" '
  def pad(n): tostring | if length < n then . + " " * (n - length) else . end;
  def cells: map(if type == "number" then (. * 10 | round / 10) else . end)
    | (.[0] | pad(16)) + (.[1:] | map(pad(10)) | join(""));
  def row(name; r; lost): [name, r.samples, lost, r.p50_us, r.p99_us, r.p999_us, r.max_us] | cells;
  (["", "answered", "lost", "p50_us", "p99_us", "p99.9_us", "max_us"] | cells),
  row("raw LCM ping"; $ping[0].round_trip_us; $ping[0].lost),
  row("request"; $req[0].round_trip_us; $req[0].lost),
  row("daemon compute"; $req[0].compute_us; "-")
'
jq -r -n --slurpfile ping "$out/ping.json" --slurpfile req "$out/requests.json" '
  def r2: . * 100 | round / 100;
  ($ping[0].round_trip_us) as $p | ($req[0].round_trip_us) as $q | ($req[0].accuracy) as $a |
  "request / ping: p50 \($q.p50_us / $p.p50_us | r2)x, p99 \($q.p99_us / $p.p99_us | r2)x, p99.9 \($q.p999_us / $p.p999_us | r2)x",
  "statuses: \($req[0].statuses | tostring)",
  "accuracy (\($a.against)): mean \($a.mean_position_mm * 10000 | round / 10000) mm, max \($a.max_position_mm * 10000 | round / 10000) mm, mean \($a.mean_orientation_deg * 10000 | round / 10000) deg"
'
grep -h "stepcal-runtime:" "$out/daemon.log" | head -1
echo "results: $out/ping.json $out/requests.json"
lost=$(jq -n --slurpfile ping "$out/ping.json" --slurpfile req "$out/requests.json" \
  '$ping[0].lost + $req[0].lost')
[[ $lost == 0 ]] || { echo "lcm_roundtrip: $lost requests or pings got no reply" >&2; exit 1; }
