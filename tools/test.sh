#!/usr/bin/env bash
# Quick start, command 2: install what is missing, build every target (the tests, fuzzers and
# benches beside `stepcal`) and run the whole test suite (ctest). The fast unit tests alone, once
# built: ctest --test-dir build -L unit.
set -euo pipefail
cd "$(dirname "$0")/.."
tools/setup.sh
ctest --test-dir build --output-on-failure -j"$(nproc)" "$@"
