#!/usr/bin/env bash
# stepcal used from outside its tree (ctest install_consumer, docs/install.md):
#  1. `cmake --install` of the build into a temporary prefix, then a consumer project
#     (tests/system/consumer) configured with find_package(stepcal 0.1 REQUIRED COMPONENTS runtime),
#     built and run: one correctForward with the model at a measured campaign row, checked against
#     the measured position;
#  2. the same consumer compiled with the installed pkg-config file (stepcal-runtime);
#  3. the package refuses an incompatible version and a component it does not have;
#  4. stepcal's source added to the consumer with add_subdirectory and only the runtime and the
#     daemon built (STEPCAL_BUILD_TESTS/TOOLS/TRAINER=OFF): it builds, and every header it
#     compiled and every shared library the daemon loads comes from Eigen's, LCM's, the C/C++
#     toolchain's or glibc's Debian packages (dpkg -S), nothing else.
#
# Usage: tests/system/install_consumer.sh BUILD_DIR MODEL CAMPAIGN_DIR WORK_DIR
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
build=$1 model=$2 campaign=$3 work=$4
rm -rf "$work"
mkdir -p "$work"
prefix=$work/prefix
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)

for component in dev stepcal; do
  cmake --install "$build" --prefix "$prefix" --component "$component" >"$work/install-$component.log"
done
read -r -a row < <("$root/tests/system/campaign_row.sh" "$campaign")

echo "1. find_package(stepcal 0.1 REQUIRED COMPONENTS runtime) from $prefix"
cmake -S "$root/tests/system/consumer" -B "$work/find-package" -DCMAKE_PREFIX_PATH="$prefix" \
  -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" >"$work/find-package.log"
cmake --build "$work/find-package" >>"$work/find-package.log"
"$work/find-package/consumer" "$model" "${row[@]}"

echo "2. pkg-config stepcal-runtime"
pc=$(find "$prefix" -name stepcal-runtime.pc)
flags=$(PKG_CONFIG_PATH=$(dirname "$pc") pkg-config --cflags --libs stepcal-runtime)
echo "   $flags"
# shellcheck disable=SC2086
${CXX:-c++} -std=c++17 -O2 "$root/tests/system/consumer/main.cpp" $flags -o "$work/consumer-pkg-config"
"$work/consumer-pkg-config" "$model" "${row[@]}"

echo "3. refusals"
for case in "0.2 COMPONENTS runtime:incompatible|not compatible|version" \
            "0.1 COMPONENTS warp_drive:warp_drive"; do
  request=${case%%:*} expected=${case#*:}
  mkdir -p "$work/refuse"
  printf 'cmake_minimum_required(VERSION 3.22)\nproject(refuse LANGUAGES CXX)\nfind_package(stepcal %s REQUIRED)\n' \
    "$request" >"$work/refuse/CMakeLists.txt"
  if out=$(cmake -S "$work/refuse" -B "$work/refuse/build" -DCMAKE_PREFIX_PATH="$prefix" 2>&1); then
    echo "find_package(stepcal $request) was accepted" >&2
    exit 1
  fi
  grep -Eq "$expected" <<<"$out" || { echo "$out" >&2; echo "no '$expected' in the refusal" >&2; exit 1; }
  echo "   find_package(stepcal $request): refused"
  rm -rf "$work/refuse"
done

echo "4. add_subdirectory(stepcal) with STEPCAL_BUILD_TESTS/TOOLS/TRAINER=OFF"
# No build type: unoptimised, so that this second build of the runtime costs CI less time (the
# optimised build is the test build's own).
cmake -S "$root/tests/system/consumer" -B "$work/subdirectory" -DSTEPCAL_SOURCE_DIR="$root" \
  -DCMAKE_BUILD_TYPE= "${launcher[@]}" >"$work/subdirectory.log"
cmake --build "$work/subdirectory" -j"$(nproc)" >>"$work/subdirectory.log"
"$work/subdirectory/consumer" "$model" "${row[@]}"
daemon=$work/subdirectory/stepcal/bin/stepcal-runtime
"$daemon" --help >/dev/null
# Packages of the headers compiled (the compiler's depfiles) and of the daemon's shared libraries.
allowed='^(libeigen3-dev|liblcm-dev|liblcm1|libsodium-dev|libsodium23|libglib2.0-0|libpcre2-8-0|libc6|libc6-dev|linux-libc-dev|libstdc\+\+-[0-9]+-dev|libstdc\+\+6|libgcc-[0-9]+-dev|libgcc-s1|gcc-[0-9]+|cpp-[0-9]+)$'
headers=$(find "$work/subdirectory" -name '*.o.d' -exec cat {} + | tr ' \\' '\n\n' |
          grep -E '^/usr/' | sort -u)
libraries=$(ldd "$daemon" | awk '$3 ~ /^\// { print $3 }')
# dpkg -S knows a file by the path its package ships it at: /lib/… or /usr/lib/… (merged /usr).
owners() {
  local paths=("$@") found unknown=() alternatives=()
  found=$(dpkg -S "${paths[@]}" 2>/dev/null || true)
  for p in "${paths[@]}"; do
    grep -qF ": $p" <<<"$found" || unknown+=("$p")
  done
  for p in "${unknown[@]}"; do
    case $p in
      /usr/lib/*) alternatives+=("${p#/usr}") ;;
      /lib/*) alternatives+=("/usr$p") ;;
      *) alternatives+=("$(realpath -e "$p")") ;;
    esac
  done
  if ((${#alternatives[@]})); then
    found+=$'\n'$(dpkg -S "${alternatives[@]}" 2>/dev/null || true)
    for p in "${alternatives[@]}"; do
      grep -qF ": $p" <<<"$found" || echo "unknown-file:$p"
    done
  fi
  grep -F ': ' <<<"$found" | cut -d: -f1 | tr ',' '\n' | sed 's/^ *//'
}
mapfile -t files < <({ echo "$headers"; echo "$libraries"; } | grep . | sort -u)
packages=$(owners "${files[@]}" | sort -u)
echo "   ${#files[@]} headers and libraries, from: $(tr '\n' ' ' <<<"$packages")"
others=$(grep -Ev "$allowed" <<<"$packages" || true)
if [[ -n $others ]]; then
  echo "the runtime-only build used files of other packages (or of none): $others" >&2
  exit 1
fi
echo "install_consumer: all passed"
