#!/usr/bin/env bash
# Builds test_handoff with ThreadSanitizer (CMake option STEPCAL_TSAN: the runtime library and
# the executables linking it) and runs it; any reported race fails the run.
#
# Usage: tests/system/tsan_check.sh [gtest arguments]
# Build folder: $STEPCAL_TSAN_DIR, default build-tsan/ in the repository. Compiler: $CXX, else
# CMake's default. Exit status 77 (skipped, with the reason) where the compiler has no TSan
# runtime or TSan cannot run on this machine; ctest's tsan_handoff counts it as skipped.
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
out=${STEPCAL_TSAN_DIR:-$root/build-tsan}
mkdir -p "$out"

export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 ${TSAN_OPTIONS:-}"
# GCC 12's TSan cannot place its shadow memory under the address-space randomisation of recent
# kernels ("unexpected memory mapping"); run without randomisation where setarch allows it.
run=()
setarch "$(uname -m)" -R true 2>/dev/null && run=(setarch "$(uname -m)" -R)

# A two-thread program first: whether TSan links and runs here at all.
probe=$out/tsan-probe
printf '#include <thread>\nint main() { std::thread t([] {}); t.join(); }\n' >"$probe.cpp"
if ! "${CXX:-c++}" -fsanitize=thread -pthread "$probe.cpp" -o "$probe" 2>"$probe.log"; then
  echo "tsan_check: skipped: ${CXX:-c++} cannot link -fsanitize=thread (no TSan runtime, e.g. libtsan2): $(head -1 "$probe.log")"
  exit 77
fi
if ! "${run[@]}" "$probe" 2>"$probe.log"; then
  echo "tsan_check: skipped: a TSan program cannot run on this machine: $(head -1 "$probe.log")"
  exit 77
fi

# -O1 -g1: TSan's reports keep their lines, and the build costs about half of -O2 -g.
cmake -S "$root" -B "$out" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" -DSTEPCAL_TSAN=ON >"$out/configure.log"
cmake --build "$out" -j"$(nproc)" --target test_handoff >"$out/build.log"
exec "${run[@]}" "$out/bin/test_handoff" "$@"
