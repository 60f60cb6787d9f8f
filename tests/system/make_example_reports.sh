#!/usr/bin/env bash
# The reports the browser tests open (ctest label browser), made with the stepcal command:
#   calibration.html, diagnosis.html              the simulated IRB4400, paper protocol, seed 1
#   certificate.html                              its ISO 9283 certificate (stepcal plan --iso9283)
#   diagnosis-backlash.html                       the same robot hiding a backlash of joint 2 (seed 3)
#   calibration-ur10C.html, diagnosis-ur10C.html  the real UR10, Series C (rows from 2000 held out)
#   tests/system/make_example_reports.sh STEPCAL OUT_DIR UR10_DATA_DIR   (tests/data/ipa-robot-accuracy)
# Without the UR10 data, its reports get a .skip file saying why instead.
set -euo pipefail

stepcal=$1
out=$2
data=$3
mkdir -p "$out"
rm -rf "$out"/*

"$stepcal" simulate --robot irb4400 --protocol paper --seed 1 --out "$out/paper" >/dev/null
"$stepcal" calibrate "$out/paper" --out "$out/paper.stepcal" --report "$out/calibration.html" >/dev/null
"$stepcal" diagnose "$out/paper" --model "$out/paper.stepcal" --report "$out/diagnosis.html" >/dev/null
"$stepcal" plan --robot irb4400 --iso9283 --rated-load-kg 60 --out "$out/iso.csv" >/dev/null
"$stepcal" simulate --robot irb4400 --protocol paper --seed 1 --poses "$out/iso.csv" --out "$out/iso" >/dev/null
"$stepcal" certify "$out/paper.stepcal" "$out/iso" --html "$out/certificate.html" >/dev/null

"$stepcal" simulate --robot irb4400 --protocol paper --seed 3 --out "$out/backlash" \
  --effect '{"name": "backlash", "joint": 2, "lost_motion_rad": 2e-4}' >/dev/null
"$stepcal" diagnose "$out/backlash" --report "$out/diagnosis-backlash.html" >/dev/null

series_c=$data/Series_C/measurements_random_poses.csv
if [[ -f $series_c ]]; then
  "$stepcal" import ipa "$series_c" --validation-from-row 2000 --out "$out/ur10C" >/dev/null
  "$stepcal" calibrate "$out/ur10C" --out "$out/ur10C.stepcal" --report "$out/calibration-ur10C.html" >/dev/null
  "$stepcal" diagnose "$out/ur10C" --model "$out/ur10C.stepcal" --report "$out/diagnosis-ur10C.html" >/dev/null
else
  for report in calibration-ur10C diagnosis-ur10C; do
    echo "no UR10 data at $series_c" >"$out/$report.html.skip"
  done
fi
