#!/usr/bin/env bash
# Smoke check of the CAN environment that tests/system/vcan_run.sh gives a command:
#   tests/system/vcan_run.sh tests/system/vcan_smoke.sh
# Checks: vcan0 is up; a data frame sent with cansend reaches candump; a CAN error frame
# (CAN_ERR_FLAG 0x20000000 in the id) sent from userspace on vcan0 reaches a CAN_RAW socket
# that enabled error frames (CAN_RAW_ERR_FILTER, candump's ",#FFFFFFFF") and not one that did
# not; the CPU has what -march=x86-64-v3 binaries need; in the VM, LCM's multicast loops on lo.
# Prints one line per check and exits 1 if any failed.
set -euo pipefail

failed=0
ok() { echo "vcan_smoke: ok: $*"; }
bad() {
  echo "vcan_smoke: FAIL: $*" >&2
  failed=1
}

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# Sends frame $2 on vcan0 every 0.2 s until candump $1 (a pid, under `timeout 30`) has exited:
# the first send could otherwise happen before candump has bound its socket. Bounded by
# candump's timeout, not by a count of sends: under emulation on a loaded host each exec is slow.
send_until_received() {
  local pid=$1 frame=$2
  while kill -0 "$pid" 2>/dev/null; do
    cansend vcan0 "$frame"
    sleep 0.2
  done
  wait "$pid" || true
}

echo "vcan_smoke: kernel $(uname -r), in the VM: ${STEPCAL_IN_VCAN_VM:-0}"

if ip link show dev vcan0 2>/dev/null | grep -q '[<,]UP[,>]'; then
  ok "vcan0 is up"
else
  bad "vcan0 is missing or down"
fi

if ! command -v cansend >/dev/null 2>&1 || ! command -v candump >/dev/null 2>&1; then
  bad "cansend/candump not found: apt-get install can-utils"
else
  # 1. A data frame.
  timeout 30 candump -n 1 -L vcan0 >"$tmp/data" 2>&1 &
  send_until_received $! 123#DEADBEEF
  if grep -q ' vcan0 123#DEADBEEF$' "$tmp/data"; then
    ok "data frame 123#DEADBEEF sent by cansend received by candump"
  else
    bad "data frame not received by candump: $(tr '\n' ' ' <"$tmp/data")"
  fi

  # 2. An error frame injected from userspace: CAN_ERR_FLAG | CAN_ERR_BUSOFF (0x40). cansend
  # sets CAN_EFF_FLAG too for an 8-digit id, so the socket sees can_id 0xA0000040.
  # Only error frames (0~0 matches no data frame) with every error class enabled.
  timeout 30 candump -n 1 -L 'vcan0,0~0,#FFFFFFFF' >"$tmp/err" 2>&1 &
  send_until_received $! 20000040#0000000000000000
  if grep -qi ' vcan0 20000040#0000000000000000$' "$tmp/err"; then
    ok "error frame 20000040# (bus-off) passes vcan to a CAN_RAW socket with CAN_RAW_ERR_FILTER"
  else
    bad "error frame not received with CAN_RAW_ERR_FILTER=0xFFFFFFFF: $(tr '\n' ' ' <"$tmp/err")"
  fi

  # 3. The same frame must not reach a socket that did not ask for error frames (candump's
  # default: all data frames, error mask 0). -T: stop after 1.5 s without a frame.
  candump -T 1500 -L vcan0 >"$tmp/noerr" 2>&1 &
  pid=$!
  for ((i = 0; i < 5; i++)); do
    cansend vcan0 20000040#0000000000000000
    sleep 0.2
  done
  wait "$pid" || true
  if [[ -s $tmp/noerr ]]; then
    bad "a socket without CAN_RAW_ERR_FILTER got: $(tr '\n' ' ' <"$tmp/noerr")"
  else
    ok "the error frame does not reach a CAN_RAW socket without CAN_RAW_ERR_FILTER"
  fi
fi

# What binaries built with -march=x86-64-v3 use (under TCG, -cpu max must provide them).
missing=()
for f in avx avx2 fma bmi1 bmi2 f16c movbe abm xsave; do
  grep -qw "$f" /proc/cpuinfo || missing+=("$f")
done
if ((${#missing[@]})); then
  bad "CPU lacks ${missing[*]} (x86-64-v3 binaries will die with SIGILL)"
else
  ok "CPU has AVX2, FMA, BMI1/2, F16C, MOVBE, LZCNT (x86-64-v3)"
fi

# LCM's udpm:// URL (239.255.76.67, ttl=0) must loop back on lo: in the VM the init sets that up.
if [[ ${STEPCAL_IN_VCAN_VM:-0} == 1 ]]; then
  if ip route get 239.255.76.67 2>/dev/null | grep -q ' dev lo ' &&
    ip link show dev lo | grep -q MULTICAST; then
    ok "multicast 239.255.76.67 routes to lo (LCM)"
  else
    bad "multicast is not routed to lo: $(ip route get 239.255.76.67 2>&1 | head -n1)"
  fi
fi

if ((failed)); then
  echo "vcan_smoke: FAILED" >&2
  exit 1
fi
echo "vcan_smoke: all checks passed"
