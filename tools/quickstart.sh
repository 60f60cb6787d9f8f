#!/usr/bin/env bash
# Quick start, command 1: install what is missing, build the `stepcal` command only (and the
# libraries it links; the tests, fuzzers and benches are tools/test.sh's), and run the main job:
# simulate the paper's IRB4400 campaign, calibrate it and print its accuracy table.
set -euo pipefail
cd "$(dirname "$0")/.."
tools/setup.sh stepcal
build/bin/stepcal demo --out out/demo-campaign "$@"
