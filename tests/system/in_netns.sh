#!/usr/bin/env bash
# Runs a command in a private network namespace with multicast on its loopback, so that LCM's
# udpm:// provider works there and nothing leaves the machine or meets other runs' traffic.
# STEPCAL_NETNS=1 tells the command it is in one (tests that need real UDP multicast skip
# without it).
#
# Usage (root): tests/system/in_netns.sh COMMAND [ARG ...]
# Exit status: the command's, 2 usage, 77 skipped (this machine does not permit `unshare -n`).
set -euo pipefail

if [[ $# -lt 1 ]]; then
  sed -n '2,8p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 2
fi
if [[ -z ${STEPCAL_NETNS:-} ]]; then
  if [[ $(id -u) -ne 0 ]] || ! unshare -n true 2>/dev/null; then
    echo "in_netns: skipped: this machine does not permit a network namespace (unshare -n; needs root or CAP_SYS_ADMIN)"
    exit 77
  fi
  STEPCAL_NETNS=1 exec unshare -n "$0" "$@"
fi
ip link set lo up
ip route add 224.0.0.0/4 dev lo
exec "$@"
