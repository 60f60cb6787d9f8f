#!/usr/bin/env bash
# Installs the Debian packages stepcal needs (only those missing) and builds it into build/.
# Safe to run again: a second run installs nothing and rebuilds only what changed.
#
#   tools/setup.sh                 every target (tests, fuzzers, benches), and the CAN tests' VM kernel
#   tools/setup.sh TARGET...       only these targets and what they need (tools/quickstart.sh: stepcal)
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(
  build-essential cmake pkg-config git clang libclang-rt-14-dev
  libeigen3-dev libgtest-dev libbenchmark-dev
  liburdfdom-dev libtinyxml-dev libyaml-cpp-dev libcli11-dev nlohmann-json3-dev liblbfgspp-dev
  liblcm-dev liblcm-bin jq
  # The runtime's message authentication (--key-file): libsodium's crypto_auth.
  libsodium-dev
  # The code-shape check's reader of functions (tests/system/check_code_shape.py).
  universal-ctags
  # check_urdf, which the calibrated URDF export's test runs on its output.
  liburdfdom-tools
  # The bench's side-by-side with KDL (stepcal-bench --compare-kdl) and the machine's own
  # latency baseline (cyclictest, docs/runtime.md).
  liborocos-kdl-dev rt-tests
  # CAN tests without vcan in the host kernel: tests/system/vcan_run.sh boots a qemu VM (docs/vcan.md).
  qemu-system-x86 busybox-static can-utils kmod xz-utils iproute2
  # The HTML reports opened in a real browser (ctest label browser, tests/system/check_report_in_browser.sh).
  chromium
  # The Python module (python/, built for Debian's /usr/bin/python3) and its pytest suite.
  python3-dev pybind11-dev python3-pybind11 python3-numpy python3-pytest
  # The Debian packages (cpack -G DEB: dpkg-shlibdeps needs file; ctest deb_package).
  file dpkg-dev
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}"
  sudo_cmd=()
  [[ $(id -u) -eq 0 ]] || sudo_cmd=(sudo)
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends \
    "${missing[@]}"
fi

cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
if (($#)); then
  cmake --build build -j"$(nproc)" --target "$@"
else
  cmake --build build -j"$(nproc)"
  # The CAN tests' VM kernel, downloaded and cached once (one line; a host with vcan0 needs none).
  tests/system/vcan_run.sh --prepare
fi
