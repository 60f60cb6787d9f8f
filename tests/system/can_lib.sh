# Shared by the end-to-end CAN scripts (can_e2e.sh, can_faults.sh); sourced, not run.
# Sets bin, iface and url from STEPCAL_BIN_DIR (default build/bin), STEPCAL_CAN_IFACE (default
# vcan0) and LCM_URL; keeps the background processes in `pids` and stops them on exit.

bin=$(realpath "${STEPCAL_BIN_DIR:-$root/build/bin}")
iface=${STEPCAL_CAN_IFACE:-vcan0}
url=${LCM_URL:-udpm://239.255.76.67:7667?ttl=0}

pids=()
can_cleanup() {
  for pid in "${pids[@]}"; do kill -TERM "$pid" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null || true; done
}
trap can_cleanup EXIT

# can_start_daemon MODEL LOG RATE_HZ MAX_AGE_MS BUDGET_US: stepcal-runtime on the live sensor of
# iface, republishing its samples on STEPCAL_WRENCH; its pid is daemon_pid (and in pids).
can_start_daemon() {
  "$bin/stepcal-runtime" --model "$1" --lcm-url "$url" --sensor "can:$iface" \
    --sensor-rate-hz "$3" --max-wrench-age-ms "$4" --budget-us "$5" \
    --sensor-republish STEPCAL_WRENCH 2>"$2" &
  daemon_pid=$!
  pids+=("$daemon_pid")
}

# can_wait_ok NAME LOG...: waits until a forward request with the live wrench is answered OK
# (within seconds; the bound of about 3 min is for a starved VM); else prints the logs, fails.
can_wait_ok() {
  local name=$1
  shift
  for _ in $(seq 600); do
    if "$bin/stepcal-client" --lcm-url "$url" --forward 0 0 0 0 28.64788975654116 0 --timeout-ms 200 --json \
        2>/dev/null | jq -e '.status == "OK"' >/dev/null; then
      return 0
    fi
    sleep 0.1
  done
  echo "$name: the daemon does not answer OK with the live sensor" >&2
  cat "$@" >&2
  return 1
}
