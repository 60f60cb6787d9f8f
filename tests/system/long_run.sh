#!/usr/bin/env bash
# The long run: REQUESTS correction requests over real UDP multicast LCM (half forward, half
# inverse, from two stepcal-client processes at a fixed rate each) to stepcal-runtime built with
# AddressSanitizer, in a private network namespace, while a swapper replaces the daemon's model
# file every SWAP_S seconds as the trainer does (a temporary file beside it, then mv) and sends
# SIGHUP. The models cycle through three calibrations of the twin's seed 11 (as measured, with a
# hidden backlash, with a hidden thermal expansion: one tracker placement, so that the requests'
# poses fit all three); the second replacement is a corrupt file (one byte flipped), which the
# daemon must refuse, keeping the model in service. Every reply is recomputed offline with the model it names
# (stepcal-client --check-model); the daemon's VmRSS is sampled every second.
#
# Usage (root): tests/system/long_run.sh [REQUESTS]     (default 1000000)
# Environment: STEPCAL_BIN_DIR (the `stepcal` command that makes the models and the clients;
# default build/bin), STEPCAL_ASAN_DIR (the ASan build of the daemon, configured and built here;
# default build-asan), RATE_HZ (requests per second per client, default 500), SWAP_S (default 3),
# CHUNK (requests per client process, default 50000: a client keeps all its requests and replies),
# RSS_GROWTH_LIMIT_MB (default 32), OUT (results; the models are kept there and reused; default
# a temporary folder). Exit status: 0 every check passed, 1 one failed, 2 usage, 77 skipped (this
# machine does not permit `unshare -n`).
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
if [[ $# -gt 1 || ${1:-} == -* ]]; then
  sed -n '2,19p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 2
fi
requests=${1:-1000000}
rate_hz=${RATE_HZ:-500}
swap_s=${SWAP_S:-3}
chunk=${CHUNK:-50000}
# A 4 MB socket receive buffer (where net.core.rmem_max allows): every socket sees all traffic of
# both clients, and a stall of the loaded machine overflows the default 208 kB.
url=${LCM_URL:-udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304}
out=${OUT:-$(mktemp -d /tmp/long_run.XXXXXX)}
asan=${STEPCAL_ASAN_DIR:-$root/build-asan}
mkdir -p "$out"
out=$(realpath "$out")
models=$out/models
# Seed 11's campaign measured three ways. One seed, because the twin draws the tracker's
# placement per seed and inverse requests carry poses in the tracker's frame: for a model of
# another seed they lie metres from the arm (UNREACHABLE at once, docs/runtime.md).
names=(11 11-backlash 11-thermal)
effect_of() {
  case $1 in
    11-backlash) echo '{"name": "backlash", "joint": 2, "lost_motion_rad": 2e-4}' ;;
    11-thermal) echo '{"name": "thermal_expansion", "expansion_per_k": 1.2e-5, "reference_temp_c": 20}' ;;
  esac
}

if [[ -z ${STEPCAL_IN_NETNS:-} ]]; then
  if [[ $(id -u) -ne 0 ]] || ! unshare -n true 2>/dev/null; then
    echo "long_run: skipped: this machine does not permit a network namespace (unshare -n; needs root or CAP_SYS_ADMIN)"
    exit 77
  fi
  command -v jq >/dev/null || { echo "long_run: needs jq (apt-get install jq)" >&2; exit 2; }
  stepcal=$(realpath "${STEPCAL_BIN_DIR:-$root/build/bin}")/stepcal
  [[ -x $stepcal ]] || { echo "long_run: $stepcal: not built (set STEPCAL_BIN_DIR)" >&2; exit 2; }

  echo "ASan build of stepcal-runtime in $asan ..."
  # -O1 -g1: what ASan needs (every access instrumented, line numbers in its reports) at about
  # half the compile time of RelWithDebInfo's -O2 -g (docs/runtime.md). Configured every time, so
  # that a folder made with other flags is brought to these; only the daemon and the libraries
  # it links are built (the clients, the test's harness, are the release build's: half the
  # compilations, client.cpp with CLI11 and the twin among them).
  flags="-fsanitize=address -fno-omit-frame-pointer"
  cmake -S "$root" -B "$asan" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS="$flags" \
    -DCMAKE_C_FLAGS="$flags" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
    -DCMAKE_EXE_LINKER_FLAGS=-fsanitize=address >"$out/asan-configure.log"
  cmake --build "$asan" -j"$(nproc)" --target stepcal-runtime >"$out/asan-build.log"

  mkdir -p "$models"
  for name in "${names[@]}"; do
    # Made again when stepcal is newer: a model a build of another format wrote is refused.
    [[ $models/model-$name.stepcal -nt $stepcal ]] && continue
    effect=$(effect_of "$name")
    # The backlash one through `stepcal diagnose`: a model with a mechanism for the daemon too.
    fit=calibrate
    [[ $name == 11-backlash ]] && fit=diagnose
    echo "model $name: stepcal simulate --seed 11${effect:+ --effect '$effect'}, stepcal $fit ..."
    "$stepcal" simulate --seed 11 ${effect:+--effect "$effect"} --out "$models/campaign-$name" >/dev/null
    "$stepcal" "$fit" "$models/campaign-$name" --out "$models/model-$name.stepcal" >/dev/null
  done
  # The corrupt model: the second one with its middle byte flipped, so its checksum fails.
  cp "$models/model-${names[1]}.stepcal" "$models/corrupt.stepcal"
  middle=$(($(stat -c %s "$models/corrupt.stepcal") / 2))
  byte=$(od -An -tu1 -j "$middle" -N1 "$models/corrupt.stepcal" | tr -d ' ')
  printf "\\$(printf %03o $((255 - byte)))" |
    dd of="$models/corrupt.stepcal" bs=1 seek="$middle" conv=notrunc status=none

  STEPCAL_IN_NETNS=1 STEPCAL_ASAN_DIR="$asan" STEPCAL_BIN_DIR="$(dirname "$stepcal")" OUT="$out" \
    exec unshare -n "$0" "$requests"
fi

ip link set lo up
ip route add 224.0.0.0/4 dev lo
client=$STEPCAL_BIN_DIR/stepcal-client
[[ -x $client ]] || { echo "long_run: $client: not built (set STEPCAL_BIN_DIR)" >&2; exit 2; }
served=$out/served.stepcal
rm -f "$out"/*.json "$out"/*.jsonl "$out"/*.log "$out"/rss.txt
cp "$models/model-${names[0]}.stepcal" "$served"
pids=()
cleanup() {
  for pid in "${pids[@]}"; do kill -TERM "$pid" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null || true; done
}
trap cleanup EXIT

# Leaks are reported when the daemon exits; a small quarantine keeps freed models from
# looking like growth.
export ASAN_OPTIONS="detect_leaks=1:quarantine_size_mb=16:${ASAN_OPTIONS:-}"
started=$(date +%s)
"$asan/bin/stepcal-runtime" --model "$served" --lcm-url "$url" 2>"$out/daemon.log" &
daemon=$!
# Subscribed once it says it serves; then the probe's requests reach it (it counts them too).
for _ in $(seq 300); do
  grep -q "stepcal-runtime: serving" "$out/daemon.log" && break
  sleep 0.1
done
probes=0
for _ in $(seq 100); do
  probes=$((probes + 1))
  probe=0  # any reply: OK or (exit status 3) another status, e.g. STALE_WRENCH
  "$client" --lcm-url "$url" --forward 0 0 0 0 28.64788975654116 0 --timeout-ms 200 >/dev/null 2>&1 || probe=$?
  [[ $probe -eq 0 || $probe -eq 3 ]] && { ready=1; break; }
  sleep 0.1
done
[[ -n ${ready:-} ]] || { echo "long_run: daemon not answering" >&2; cat "$out/daemon.log" >&2; exit 1; }

while kill -0 "$daemon" 2>/dev/null; do
  awk '/^VmRSS/ {print $2}' "/proc/$daemon/status" 2>/dev/null >>"$out/rss.txt" || true
  sleep 1
done &
pids+=($!)

# The swapper: the next model (the corrupt one at the second swap) into place by rename, then
# SIGHUP, until the file `stop` appears. swaps.log: one line per swap, the file put in place.
rm -f "$out/stop"
(
  swap=0 good=0
  while sleep "$swap_s" && [[ ! -e $out/stop ]]; do
    swap=$((swap + 1))
    if [[ $swap -eq 2 ]]; then
      next=$models/corrupt.stepcal
    else
      good=$((good + 1))
      next=$models/model-${names[$((good % ${#names[@]}))]}.stepcal
    fi
    cp "$next" "$served.tmp"
    mv -f "$served.tmp" "$served"
    kill -HUP "$daemon"
    echo "$(basename "$next")" >>"$out/swaps.log"
  done
) &
swapper=$!
pids+=($swapper)

check_args=()
for name in "${names[@]}"; do check_args+=(--check-model "$models/model-$name.stepcal"); done
campaign=$models/campaign-${names[0]}
per_client=$((requests / 2))
client_loop() {  # mode: chunks of at most $chunk requests until $per_client are sent
  local mode=$1 sent=0 k=0 n status=0
  while [[ $sent -lt $per_client ]]; do
    n=$((per_client - sent < chunk ? per_client - sent : chunk))
    "$client" --lcm-url "$url" --campaign "$campaign" --mode "$mode" --count "$n" \
      --rate "$rate_hz" --timeout-ms 2000 --json "${check_args[@]}" \
      >"$out/$mode-$k.json" 2>>"$out/$mode.log" || [[ $? -eq 3 ]] || status=1  # 3: counted below
    sent=$((sent + n))
    k=$((k + 1))
  done
  return $status
}
echo "$requests requests ($per_client forward, $per_client inverse at $rate_hz Hz each), a model swap every $swap_s s, in $out ..."
client_loop forward &
forward=$!
client_loop inverse &
inverse=$!
clients_ok=1
wait "$forward" || clients_ok=0
wait "$inverse" || clients_ok=0
touch "$out/stop"
wait "$swapper" || true
sleep 1.5  # a reload still running finishes; the RSS sampler takes its last samples
kill -TERM "$daemon"
daemon_status=0
wait "$daemon" || daemon_status=$?
duration_s=$(($(date +%s) - started))
# Datagrams the kernel dropped for full receive buffers, all sockets of the namespace.
udp_drops=$(awk '/^Udp:/ && $2 ~ /^[0-9]+$/ {print $6}' /proc/net/snmp)

# ---- the checks ------------------------------------------------------------------------------
failures=()
fail() { failures+=("$1"); }
# Each client's JSON once, without its per-row part (large).
for f in "$out"/forward-*.json "$out"/inverse-*.json; do
  jq -c '{mode, requests, replies, statuses, check}' "$f"
done >"$out/summary.jsonl"
sum() { jq -s "map($1) | add" "$out/summary.jsonl"; }
sent=$(sum .requests)
replies=$(sum .replies)
checked=$(sum .check.checked)
mismatched=$(sum .check.mismatched)
unknown=$(sum .check.unknown_model)
unreachable=$(jq -s 'map(.statuses.UNREACHABLE // 0) | add' "$out/summary.jsonl")
changes=$(sum .check.model_changes)
statuses=$(jq -s -c 'map(.statuses | to_entries[]) | group_by(.key)
  | map({(.[0].key): (map(.value) | add)}) | add' "$out/summary.jsonl")
max_difference=$(jq -s 'map(.check.max_difference) | max' "$out/summary.jsonl")
# Statuses per mode and model file: which model gave which answers.
per_model=$(jq -s -c '[.[] | .mode as $mode | .check.models[]
    | {key: "\($mode) \(.path | split("/") | last)", statuses}] | group_by(.key)
  | map({(.[0].key): (map(.statuses | to_entries[]) | group_by(.key)
    | map({(.[0].key): (map(.value) | add)}) | add)}) | add' "$out/summary.jsonl")
models_answering=$(jq -s '[.[].check.models[] | select(.replies > 0) | .path] | unique | length' \
  "$out/summary.jsonl")
# Where lost replies were lost: requests the daemon never handled were dropped on their way to
# it; replies it sent that no client took were dropped on their way back.
daemon_requests=$(sed -n 's/.*stopping after \([0-9]*\) requests, \([0-9]*\) replies.*/\1/p' "$out/daemon.log")
daemon_replies=$(sed -n 's/.*stopping after \([0-9]*\) requests, \([0-9]*\) replies.*/\2/p' "$out/daemon.log")
handled=$((${daemon_requests:-0} - probes))
lost_to_daemon=$((sent - handled))
lost_to_clients=$((${daemon_replies:-0} - probes - replies))
swaps=$(wc -l <"$out/swaps.log")
reloaded=$(grep -c "stepcal-runtime: reloaded" "$out/daemon.log" || true)
refused=$(grep -c "stepcal-runtime: reload refused" "$out/daemon.log" || true)
asan_errors=$(cat "$out"/daemon.log "$out"/forward.log "$out"/inverse.log |
  grep -c "ERROR: \(Address\|Leak\)Sanitizer" || true)
id_of() { jq -r -s --arg path "$1" '.[0].check.models[] | select(.path == $path) | .model_id' "$out/summary.jsonl"; }
# The daemon must have kept the model put in place by the first swap.
kept_expected=$(id_of "$models/model-${names[1]}.stepcal")
kept=$(sed -n 's/.*reload refused, keeping model \([0-9a-f]*\).*/\1/p' "$out/daemon.log" | head -1)
rss_first=$(head -1 "$out/rss.txt")
rss_last=$(tail -1 "$out/rss.txt")
rss_max=$(sort -n "$out/rss.txt" | tail -1)
samples=$(wc -l <"$out/rss.txt")
rss_quarter=$(sed -n "$((samples / 4 + 1))p" "$out/rss.txt")
growth_mb=$(((rss_last - rss_quarter) / 1024))

[[ $clients_ok == 1 ]] || fail "a client failed (torn answer or error: $out/forward.log, $out/inverse.log)"
[[ $sent == "$requests" && $replies == "$sent" ]] || fail "replies $replies of $sent requests (of $requests)"
[[ $checked == "$replies" && $mismatched == 0 && $unknown == 0 ]] ||
  fail "checked $checked of $replies replies: $mismatched differ from their model, $unknown name an unknown model"
[[ $refused == 1 && $kept == "$kept_expected" ]] ||
  fail "corrupt model: $refused refusals, kept model '$kept', expected $kept_expected"
[[ $reloaded == $((swaps - 1)) ]] || fail "$reloaded reloads for $swaps swaps (one of them corrupt)"
# The poses are the arm's for every model: UNREACHABLE means a model of another tracker frame.
[[ $unreachable == 0 ]] || fail "$unreachable UNREACHABLE replies: the requests' poses do not fit every model"
[[ $models_answering == "${#names[@]}" ]] || fail "replies came from $models_answering of ${#names[@]} models"
[[ $asan_errors == 0 ]] || fail "$asan_errors AddressSanitizer/LeakSanitizer reports ($out/daemon.log)"
[[ $daemon_status == 0 ]] || fail "the daemon exited with status $daemon_status"
[[ $growth_mb -le ${RSS_GROWTH_LIMIT_MB:-32} ]] ||
  fail "daemon RSS grew by $growth_mb MB from a quarter into the run to its end"

cat <<EOF
requests sent          $sent (forward and inverse, $rate_hz Hz per client)
replies received       $replies (UDP receive-buffer drops in the namespace: $udp_drops)
lost                   $((sent - replies)): $lost_to_daemon requests the daemon never handled, $lost_to_clients of its replies no client took (probe requests: $probes)
statuses               $statuses
statuses per model     $per_model
checked against model  $checked: $mismatched differ, $unknown from an unknown model, largest difference $max_difference
model swaps            $swaps ($reloaded reloaded, $refused refused: the corrupt file; kept model $kept)
model changes in replies $changes, from $models_answering models
daemon RSS (kB)        first $rss_first, at a quarter $rss_quarter, last $rss_last, max $rss_max ($samples samples)
ASan/LSan reports      $asan_errors
daemon exit status     $daemon_status
duration               $duration_s s
results                $out
EOF
if [[ ${#failures[@]} -gt 0 ]]; then
  printf 'long_run: FAILED: %s\n' "${failures[@]}" >&2
  exit 1
fi
echo "long_run: passed"
