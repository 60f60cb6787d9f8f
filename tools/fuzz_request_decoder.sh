#!/usr/bin/env bash
# Builds the request-decoder fuzzer (clang++, libFuzzer + ASan + UBSan) and runs it.
#
# Usage: tools/fuzz_request_decoder.sh [SECONDS]    (default 30)
# Work folder: $STEPCAL_FUZZ_DIR, default build-fuzz-request/ in the repository. The growing
# corpus stays in its corpus/ between runs; crashing inputs land in its artifacts/.
set -euo pipefail

seconds=${1:-30}
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
out=${STEPCAL_FUZZ_DIR:-$root/build-fuzz-request}
mkdir -p "$out/obj" "$out/corpus" "$out/seeds" "$out/artifacts" "$out/lcmtypes"

# The message classes, as the CMake build makes them (lcmtypes/CMakeLists.txt).
lcm-gen --cpp --cpp-std c++11 --cpp-hpath "$out/lcmtypes" "$root"/lcmtypes/*.lcm >/dev/null

# -fno-strict-aliasing: LCM 1.3's generated decoders need it (lcmtypes/CMakeLists.txt).
# shellcheck disable=SC2207  # pkg-config prints space-separated flags
flags=(-std=c++17 -O2 -g -Wall -Wextra -fno-strict-aliasing
  -I"$root/common/include" -I"$root/runtime/include" -I"$root/runtime/service/include"
  -isystem "$out/lcmtypes" $(pkg-config --cflags eigen3))
# Objects carry coverage instrumentation; only the fuzzer link pulls in libFuzzer's main.
# shellcheck disable=SC2054  # the commas belong to the flag
instrument=(-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined)

# Compile one object (in the background) unless it is newer than every source and header.
compile() {
  local src=$1 obj=$2
  shift 2
  if [[ -f $obj && -z $(find "$src" "$root/common/include" "$root/runtime/include" \
    "$root/runtime/service/include" "$root/lcmtypes" -newer "$obj" -print -quit) ]]; then
    return
  fi
  echo "compiling $src"
  clang++ "${flags[@]}" "${instrument[@]}" "$@" -c "$src" -o "$obj" &
  pids+=($!)
}
pids=()
compile "$root/runtime/service/src/request.cpp" "$out/obj/request.o"
compile "$root/tests/fuzz/fuzz_request_decoder.cpp" "$out/obj/fuzz_target.o"
compile "$root/tests/fuzz/fuzz_request_decoder.cpp" "$out/obj/make_seeds.o" -DSTEPCAL_FUZZ_SEED_MAIN
failed=0
for pid in "${pids[@]}"; do wait "$pid" || failed=1; done
if ((failed)); then
  echo "compilation failed" >&2
  exit 1
fi
clang++ -fsanitize=fuzzer,address,undefined "$out/obj/fuzz_target.o" "$out/obj/request.o" \
  -o "$out/fuzz_request_decoder"
clang++ -fsanitize=fuzzer-no-link,address,undefined "$out/obj/make_seeds.o" \
  -o "$out/make_seeds"
"$out/make_seeds" "$out/seeds"

# Mode and wrench-source values, and doubles the checks care about (1, NaN, ±∞, 20 and 150.5:
# a temperature inside and just outside its range).
cat > "$out/request.dict" <<'DICT'
"\x00"
"\x01"
"\x3f\xf0\x00\x00\x00\x00\x00\x00"
"\x7f\xf8\x00\x00\x00\x00\x00\x00"
"\x7f\xf0\x00\x00\x00\x00\x00\x00"
"\xff\xf0\x00\x00\x00\x00\x00\x00"
"\x40\x34\x00\x00\x00\x00\x00\x00"
"\x40\x62\xd0\x00\x00\x00\x00\x00"
DICT

"$out/fuzz_request_decoder" -max_total_time="$seconds" -print_final_stats=1 \
  -dict="$out/request.dict" -artifact_prefix="$out/artifacts/" "$out/corpus" "$out/seeds"
