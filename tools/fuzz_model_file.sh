#!/usr/bin/env bash
# Builds the model-file fuzzer (clang++, libFuzzer + ASan + UBSan) and runs it.
#
# Usage: tools/fuzz_model_file.sh [SECONDS]    (default 30)
# Work folder: $STEPCAL_FUZZ_DIR, default build-fuzz-model/ in the repository. The growing corpus
# stays in its corpus/ between runs; crashing inputs land in its artifacts/.
set -euo pipefail

seconds=${1:-30}
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
out=${STEPCAL_FUZZ_DIR:-$root/build-fuzz-model}
mkdir -p "$out/obj" "$out/corpus" "$out/seeds" "$out/artifacts"

# shellcheck disable=SC2207  # pkg-config prints space-separated flags
flags=(-std=c++17 -O2 -g -Wall -Wextra -I"$root/common/include" $(pkg-config --cflags eigen3))
sanitizers=-fsanitize=address,undefined
# Objects carry coverage instrumentation; only the fuzzer link pulls in libFuzzer's main.
instrument=(-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined)

# Compile one object (in the background) unless it is newer than every source and header.
compile() {
  local src=$1 obj=$2
  shift 2
  if [[ -f $obj && -z $(find "$src" "$root/common/include" -newer "$obj" -print -quit) ]]; then
    return
  fi
  echo "compiling $src"
  clang++ "${flags[@]}" "${instrument[@]}" "$@" -c "$src" -o "$obj" &
  pids+=($!)
}
pids=()
objects=()
for name in error lie chain compliance mechanisms model_file; do
  compile "$root/common/src/$name.cpp" "$out/obj/$name.o"
  objects+=("$out/obj/$name.o")
done
compile "$root/tests/fuzz/fuzz_model_file.cpp" "$out/obj/fuzz_target.o"
compile "$root/tests/fuzz/fuzz_model_file.cpp" "$out/obj/make_seeds.o" -DSTEPCAL_FUZZ_SEED_MAIN
failed=0
for pid in "${pids[@]}"; do wait "$pid" || failed=1; done
if ((failed)); then
  echo "compilation failed" >&2
  exit 1
fi
clang++ -fsanitize=fuzzer,address,undefined "$out/obj/fuzz_target.o" "${objects[@]}" \
  -o "$out/fuzz_model_file"
clang++ -fsanitize=fuzzer-no-link,address,undefined "$out/obj/make_seeds.o" "${objects[@]}" \
  -o "$out/make_seeds"
"$out/make_seeds" "$out/seeds"

# Section tags and the magic, so mutations can rebuild structure the checksum re-stamp keeps.
cat > "$out/model.dict" <<'DICT'
"STEPCAL\x00"
"CHAN"
"NOMI"
"REGI"
"COMP"
"GPR "
"MECH"
"PROV"
"\x01\x00\x00\x00"
"\x02\x00\x00\x00"
"\xff\xff\xff\xff"
"\x00\x00\x00\x00\x00\x00\xf0\x3f"
DICT

"$out/fuzz_model_file" -max_total_time="$seconds" -print_final_stats=1 \
  -dict="$out/model.dict" -artifact_prefix="$out/artifacts/" "$out/corpus" "$out/seeds"
