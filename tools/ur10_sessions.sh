#!/usr/bin/env bash
# The real UR10, leave one series out (README, "Several campaigns of one robot"): the geometric
# model (`poe`) fitted on three of the four series together (`stepcal calibrate X Y Z`: one
# geometry of the joints, each series its own tracker registration and tool) is validated on the
# fourth with the tracker and tool frames fitted again there (`stepcal validate --refit-frames`);
# beside it, each of the three series' own geometric model validated the same way. Mean position
# error, mm, on all rows of the left-out series.
#
# Usage: tools/ur10_sessions.sh [DATA [OUT]]
#   DATA  the IPA data set (default tests/data/ipa-robot-accuracy)
#   OUT   working folder (default out/ur10-sessions); the table is also written to OUT/table.md
# Environment: STEPCAL_BIN_DIR (default build/bin).
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
data=$(realpath "${1:-$root/tests/data/ipa-robot-accuracy}")
out=${2:-$root/out/ur10-sessions}
bin=${STEPCAL_BIN_DIR:-$root/build/bin}
command -v jq >/dev/null || { echo "ur10_sessions: needs jq (apt-get install jq)" >&2; exit 2; }
mkdir -p "$out"

declare -A csv=([A]=Series_A/measurements_grid.csv [B]=Series_B/measurements_joint_configurations.csv
                [C]=Series_C/measurements_random_poses.csv [D]=Series_D/measurements_iso_cubes.csv)
for s in A B C D; do
  [[ -f $out/$s/campaign.yaml ]] || "$bin/stepcal" import ipa "$data/${csv[$s]}" --out "$out/$s" >/dev/null
  [[ -f $out/$s.poe.stepcal ]] || "$bin/stepcal" calibrate "$out/$s" --out "$out/$s.poe.stepcal" >/dev/null
done

# mean position error (mm) of the poe layer with its frames refitted, from a validate JSON
mean() {
  jq -r '[.[] | select(.method == "poe (frames refit)")] |
         if length == 0 then "-" else (.[0].mean_position_mm * 1000 | round / 1000 | tostring) end' "$1"
}

table=$out/table.md
{
  echo "| left out | rows | fitted on | three together | each alone | best alone |"
  echo "|---|---|---|---|---|---|"
} >"$table"
for left in A B C D; do
  others=()
  for s in A B C D; do [[ $s == "$left" ]] || others+=("$s"); done
  tag=$(IFS=; echo "${others[*]}")
  model=$out/$tag.poe.stepcal
  [[ -f $model ]] || "$bin/stepcal" calibrate "${others[@]/#/$out/}" --out "$model" \
    --json >"$out/$tag.calibration.json"
  "$bin/stepcal" validate "$model" "$out/$left" --refit-frames --json >"$out/$tag-$left.json"
  together=$(mean "$out/$tag-$left.json")
  alone=() best=""
  for s in "${others[@]}"; do
    "$bin/stepcal" validate "$out/$s.poe.stepcal" "$out/$left" --refit-frames --json >"$out/$s-$left.json"
    m=$(mean "$out/$s-$left.json")
    alone+=("$s $m")
    if [[ -z $best ]] || awk -v a="$m" -v b="$best" 'BEGIN { exit !(a < b) }'; then best=$m; fi
  done
  rows=$(jq -r '[.[] | select(.method == "poe (frames refit)")][0].rows' "$out/$tag-$left.json")
  list=$(IFS=,; echo "${alone[*]}")
  echo "| $left | $rows | ${others[*]} | $together | ${list//,/, } | $best |" >>"$table"
done
cat "$table"
