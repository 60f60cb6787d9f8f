#!/usr/bin/env bash
# Builds test_handoff with ThreadSanitizer (CMake option STEPCAL_TSAN: the runtime library and
# the executables linking it) and runs it; any reported race fails the run.
#
# Usage: tools/tsan_check.sh [gtest arguments]
# Build folder: $STEPCAL_TSAN_DIR, default build-tsan/ in the repository.
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
out=${STEPCAL_TSAN_DIR:-$root/build-tsan}
cmake -S "$root" -B "$out" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSTEPCAL_TSAN=ON
cmake --build "$out" -j"$(nproc)" --target test_handoff

export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 ${TSAN_OPTIONS:-}"
# GCC 12's TSan cannot place its shadow memory under the address-space randomisation of recent
# kernels ("unexpected memory mapping"); run without randomisation where setarch allows it.
if setarch "$(uname -m)" -R true 2>/dev/null; then
  exec setarch "$(uname -m)" -R "$out/bin/test_handoff" "$@"
fi
exec "$out/bin/test_handoff" "$@"
