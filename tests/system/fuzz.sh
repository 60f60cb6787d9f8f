#!/usr/bin/env bash
# Builds one libFuzzer target of tests/fuzz (clang++, libFuzzer + ASan + UBSan) and runs it.
#
# Usage: tests/system/fuzz.sh TARGET [SECONDS]    (default 30)
#   TARGET: model_file       parseModel (the model file)
#           request_decoder  the runtime's decodeRequest
#           campaign         readCampaign (campaign.yaml + measurements.csv) and writeCampaign
#           pose_list        readPoseList (poses.csv) and writePoseList
#           ipa_import       importIpaSeries (the IPA UR10 series CSV + Trafo_TM_F_init.txt)
#           import_mapped    importMapped (mapping.yaml + tracker export + joint log + transform)
#           urdf             chainFromUrdf and bodyMassesFromUrdf
# STEPCAL_FUZZ_SEED: libFuzzer's random seed (default: a new one per run, to find what earlier
# runs did not). ctest sets 1: from the same seeds a run then tries the same inputs in the same
# order on every machine (a slower one a prefix of them), so its verdict is the code's, not luck.
# Work folder: $STEPCAL_FUZZ_DIR, default build-fuzz-TARGET/ in the repository. The growing
# corpus stays in its corpus/ between runs; crashing inputs land in its artifacts/ (re-run one
# with WORK_FOLDER/fuzz_TARGET ARTIFACT). The project's sources are compiled into
# $STEPCAL_FUZZ_OBJ_DIR (default WORK_FOLDER/obj), which several targets may share (ctest does):
# their flags are the same, and each object is written beside and renamed into place.
set -euo pipefail

if (($# < 1)); then
  echo "usage: $0 TARGET [SECONDS]; TARGET: model_file, request_decoder, campaign, pose_list," \
    "ipa_import, import_mapped, urdf" >&2
  exit 2
fi
target=$1
seconds=${2:-30}
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
out=${STEPCAL_FUZZ_DIR:-$root/build-fuzz-$target}
shared_obj=${STEPCAL_FUZZ_OBJ_DIR:-$out/obj}
mkdir -p "$out/obj" "$shared_obj" "$out/corpus" "$out/seeds" "$out/artifacts"

# shellcheck disable=SC2207  # pkg-config prints space-separated flags
# -O1 -g1: the sanitizers' stack traces keep their lines; the build costs half of -O2 -g.
flags=(-std=c++17 -O1 -g1 -Wall -Wextra -I"$root/common/include" $(pkg-config --cflags eigen3))
headers=("$root/common/include" "$root/tests/fuzz")
libs=()
seed_main=0  # 1: the target's source, built with -DSTEPCAL_FUZZ_SEED_MAIN, writes the seeds
case $target in
  model_file)
    sources=(common/src/{error,text_number,lie,chain,compliance,mechanisms,model_file,atomic_file}.cpp)
    # Each mechanism kind's own file (common/src/mechanisms/, as the CMake build globs them).
    for kind_source in "$root"/common/src/mechanisms/*.cpp; do sources+=("${kind_source#"$root"/}"); done
    seed_main=1
    ;;
  request_decoder)
    # The message classes, as the CMake build makes them (lcmtypes/CMakeLists.txt).
    mkdir -p "$out/lcmtypes"
    lcm-gen --cpp --cpp-std c++11 --cpp-hpath "$out/lcmtypes" "$root"/lcmtypes/*.lcm >/dev/null
    # -fno-strict-aliasing: LCM 1.3's generated decoders need it (lcmtypes/CMakeLists.txt).
    flags+=(-fno-strict-aliasing -I"$root/runtime/include" -I"$root/runtime/service/include"
      -isystem "$out/lcmtypes")
    headers+=("$root/runtime/include" "$root/runtime/service/include" "$root/lcmtypes")
    sources=(runtime/service/src/request.cpp)
    seed_main=1
    ;;
  campaign)
    sources=(common/src/{error,text_number,csv,campaign}.cpp)
    # shellcheck disable=SC2207
    libs=($(pkg-config --libs yaml-cpp))
    cp "$root"/tests/fuzz/seeds/campaign/* "$out/seeds/"
    ;;
  pose_list)
    sources=(common/src/{error,text_number,csv,campaign}.cpp)
    # shellcheck disable=SC2207
    libs=($(pkg-config --libs yaml-cpp))
    cp "$root"/tests/fuzz/seeds/pose_list/* "$out/seeds/"
    ;;
  ipa_import)
    flags+=(-I"$root/tools/importers/include" -DSTEPCAL_ROBOTS_DIR="\"$root/robots\"")
    headers+=("$root/tools/importers/include")
    sources=(common/src/{error,text_number,csv,lie,chain,urdf,campaign}.cpp tools/importers/src/{ipa,shared}.cpp)
    # shellcheck disable=SC2207
    libs=($(pkg-config --libs urdfdom yaml-cpp))
    # The first rows of each real series, a NUL, the series' transform.
    for series in "$root"/tests/data/ipa-robot-accuracy/Series_*; do
      { head -n 6 "$series"/measurements_*.csv; printf '\0'; cat "$series/Trafo_TM_F_init.txt"; } \
        > "$out/seeds/$(basename "$series")"
    done
    ;;
  import_mapped)
    flags+=(-I"$root/tools/importers/include" -DSTEPCAL_ROBOTS_DIR="\"$root/robots\"")
    headers+=("$root/tools/importers/include" "$root/tools/importers/src")
    sources=(common/src/{error,text_number,csv,lie,chain,urdf,campaign,robots}.cpp
      tools/importers/src/{mapped,mapping,shared}.cpp)
    # shellcheck disable=SC2207
    libs=($(pkg-config --libs urdfdom yaml-cpp))
    # The layouts of tests/test_import_mapped.cpp and a few rows of the IPA set's Series D.
    cp "$root"/tests/fuzz/seeds/import_mapped/* "$out/seeds/"
    ;;
  urdf)
    sources=(common/src/{error,text_number,lie,chain,urdf}.cpp)
    # shellcheck disable=SC2207
    libs=($(pkg-config --libs urdfdom))
    # The robots' descriptions after a line with the names their chains are read with.
    { echo "base_link tmac flange ft_sensor"; cat "$root/robots/irb4400.urdf"; } \
      > "$out/seeds/irb4400"
    { echo "base_link tool0"; cat "$root/robots/ur10.urdf"; } > "$out/seeds/ur10"
    # And the inputs it once failed on (tests/test_chain.cpp checks each is refused).
    cp "$root"/tests/data/fuzz/urdf/* "$out/seeds/"
    ;;
  *)
    echo "unknown fuzz target '$target'; expected model_file, request_decoder, campaign," \
      "pose_list, ipa_import, import_mapped or urdf" >&2
    exit 2
    ;;
esac
fuzzer=$root/tests/fuzz/fuzz_$target.cpp
# Objects carry coverage instrumentation; only the fuzzer link pulls in libFuzzer's main.
# shellcheck disable=SC2054  # the commas belong to the flag
instrument=(-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined)

# Compile one object (in the background) unless it is newer than every source and header.
compile() {
  local src=$1 obj=$2
  shift 2
  if [[ -f $obj && -z $(find "$src" "${headers[@]}" -newer "$obj" -print -quit) ]]; then
    return
  fi
  echo "compiling $src"
  # Written beside and renamed: another target's run may read the shared object meanwhile.
  (clang++ "${flags[@]}" "${instrument[@]}" "$@" -c "$src" -o "$obj.$$.tmp" && mv "$obj.$$.tmp" "$obj") &
  pids+=($!)
}
pids=()
objects=()
for src in "${sources[@]}"; do
  obj=$shared_obj/$(basename "$src" .cpp).o
  compile "$root/$src" "$obj"
  objects+=("$obj")
done
compile "$fuzzer" "$out/obj/fuzz_target.o"
if ((seed_main)); then
  compile "$fuzzer" "$out/obj/make_seeds.o" -DSTEPCAL_FUZZ_SEED_MAIN
fi
failed=0
for pid in "${pids[@]}"; do wait "$pid" || failed=1; done
if ((failed)); then
  echo "compilation failed" >&2
  exit 1
fi
clang++ -fsanitize=fuzzer,address,undefined "$out/obj/fuzz_target.o" "${objects[@]}" "${libs[@]}" \
  -o "$out/fuzz_$target"
if ((seed_main)); then
  clang++ -fsanitize=fuzzer-no-link,address,undefined "$out/obj/make_seeds.o" "${objects[@]}" \
    -o "$out/make_seeds"
  "$out/make_seeds" "$out/seeds"
fi

# The targets that read files write them per input; in memory that costs least.
if [[ -z ${TMPDIR:-} && -w /dev/shm ]]; then export TMPDIR=/dev/shm; fi
export LSAN_OPTIONS=suppressions=$root/tests/fuzz/urdfdom.supp
# A hang is a finding too: no input of these sizes needs more than a fraction of a second, even
# on a loaded host.
seed=()
[[ -n ${STEPCAL_FUZZ_SEED:-} ]] && seed=(-seed="$STEPCAL_FUZZ_SEED")
"$out/fuzz_$target" "${seed[@]}" -max_total_time="$seconds" -timeout=25 -print_final_stats=1 \
  -dict="$root/tests/fuzz/$target.dict" -artifact_prefix="$out/artifacts/" \
  "$out/corpus" "$out/seeds"
