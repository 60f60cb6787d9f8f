#!/usr/bin/env bash
# The re-check on the real UR10 (docs/cell.md, "The re-check"): Series A's models (geometric and
# extended) re-checked with twenty rows of Series D, the other 612 becoming set=validation, by
# default and with --keep-tool, beside A's models with the tracker and tool refitted on all of D
# (`stepcal validate --refit-frames`, the README's A→D). Two choices of the twenty: D20, every
# 31st row from the first; D20plan, the twenty `stepcal plan --recheck A.extended.stepcal
# --candidates-from D` chooses among D's measured poses.
#
# Usage: tools/ur10_recheck.sh [DATA [OUT]]
#   DATA  the IPA data set (default tests/data/ipa-robot-accuracy)
#   OUT   working folder (default out/recheck); files already there are reused
# Environment: STEPCAL_BIN_DIR (default build/bin).
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
data=$(realpath "${1:-$root/tests/data/ipa-robot-accuracy}")
out=${2:-$root/out/recheck}
bin=${STEPCAL_BIN_DIR:-$root/build/bin}
mkdir -p "$out"

[[ -f $out/A/campaign.yaml ]] ||
  "$bin/stepcal" import ipa "$data/Series_A/measurements_grid.csv" --out "$out/A" >/dev/null
[[ -f $out/D/campaign.yaml ]] ||
  "$bin/stepcal" import ipa "$data/Series_D/measurements_iso_cubes.csv" --out "$out/D" >/dev/null
if [[ ! -f $out/A.extended.stepcal ]]; then
  "$bin/stepcal" calibrate "$out/A" --out "$out/A.poe.stepcal" >/dev/null
  "$bin/stepcal" diagnose "$out/A" --model "$out/A.poe.stepcal" --out "$out/A.extended.stepcal" >/dev/null
fi

# Twenty rows of D to fit (row index 0, 31, …, 589), the rest to validate.
rm -rf "$out/D20"
cp -r "$out/D" "$out/D20"
awk -F, -v OFS=, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "set") c = i; print; next }
                  { $c = ((NR - 2) % 31 == 0 && NR - 2 < 620) ? "geometry" : "validation"; print }' \
  "$out/D/measurements.csv" >"$out/D20/measurements.csv"

# The re-check's plan: twenty of D's poses.
"$bin/stepcal" plan --recheck "$out/A.extended.stepcal" --poses 20 --candidates-from "$out/D" \
  --out "$out/D-plan20.csv" >/dev/null 2>&1
rm -rf "$out/D20plan"
cp -r "$out/D" "$out/D20plan"
awk -F, -v OFS=, 'NR == FNR { if (FNR > 1) planned[$1] = 1; next }
                  FNR == 1 { for (i = 1; i <= NF; i++) { if ($i == "set") c = i; if ($i == "pose_id") p = i }
                             print; next }
                  { $c = ($p in planned) ? "geometry" : "validation"; print }' \
  "$out/D-plan20.csv" "$out/D/measurements.csv" >"$out/D20plan/measurements.csv"

for model in A.poe A.extended; do
  echo "== $model, A->D with the frames refitted on all of D"
  "$bin/stepcal" validate "$out/$model.stepcal" "$out/D" --refit-frames | tail -1
  echo "== $model re-checked on twenty rows of D"
  "$bin/stepcal" recheck "$out/$model.stepcal" "$out/D20" --out "$out/$model.recheck.stepcal"
  echo "== $model re-checked on twenty rows of D, the tool kept"
  "$bin/stepcal" recheck "$out/$model.stepcal" "$out/D20" --keep-tool \
    --out "$out/$model.recheck-keep-tool.stepcal"
  echo "== $model re-checked on the planner's twenty rows of D"
  "$bin/stepcal" recheck "$out/$model.stepcal" "$out/D20plan" --out "$out/$model.recheck-plan.stepcal"
  echo "== $model re-checked on the planner's twenty rows of D, the tool kept"
  "$bin/stepcal" recheck "$out/$model.stepcal" "$out/D20plan" --keep-tool \
    --out "$out/$model.recheck-plan-keep-tool.stepcal"
done
