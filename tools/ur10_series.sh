#!/usr/bin/env bash
# The real UR10 across its four series (docs/diagnosis.md, "On the real UR10"): each source series is
# calibrated (the geometric model, `poe`) and diagnosed (the extended model), and both are
# validated on later rows of the same series, or on another series with the tracker and tool
# frames fitted again there (`stepcal validate --refit-frames`): mean position error, mm, on all
# rows and on the rows whose joint angles every transmission profile covers.
#
# Usage: tools/ur10_series.sh [DATA [OUT]]
#   DATA  the IPA data set (default tests/data/ipa-robot-accuracy)
#   OUT   working folder (default out/ur10-series); the table is also written to OUT/table.md
# Environment: STEPCAL_BIN_DIR (default build/bin).
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
data=$(realpath "${1:-$root/tests/data/ipa-robot-accuracy}")
out=${2:-$root/out/ur10-series}
bin=${STEPCAL_BIN_DIR:-$root/build/bin}
command -v jq >/dev/null || { echo "ur10_series: needs jq (apt-get install jq)" >&2; exit 2; }
mkdir -p "$out"

declare -A csv=([A]=Series_A/measurements_grid.csv [B]=Series_B/measurements_joint_configurations.csv
                [C]=Series_C/measurements_random_poses.csv [D]=Series_D/measurements_iso_cubes.csv)
# Same-series cases fit the first rows and hold out the rest.
declare -A split=([C]=2000 [A]=8000)

for s in A B C D; do
  [[ -f $out/$s/campaign.yaml ]] || "$bin/stepcal" import ipa "$data/${csv[$s]}" --out "$out/$s" >/dev/null
done
for s in "${!split[@]}"; do
  [[ -f $out/$s-split/campaign.yaml ]] ||
    "$bin/stepcal" import ipa "$data/${csv[$s]}" --validation-from-row "${split[$s]}" \
      --out "$out/$s-split" >/dev/null
done

# Geometric and extended models of each source.
for src in A B C A-split C-split; do
  if [[ ! -f $out/$src.extended.stepcal ]]; then
    "$bin/stepcal" calibrate "$out/$src" --out "$out/$src.poe.stepcal" >/dev/null
    /usr/bin/time -f "%e" -o "$out/$src.seconds" "$bin/stepcal" diagnose "$out/$src" \
      --model "$out/$src.poe.stepcal" --out "$out/$src.extended.stepcal" --json \
      >"$out/$src.diagnosis.json"
  fi
done

# mean position error (mm) of a method, or "-"; $1 = validate JSON, $2 = method, $3 = set filter
mean() {
  jq -r --arg m "$2" --arg s "$3" \
    '[.[] | select(.method == $m and ($s == "" or .set == $s))] |
     if length == 0 then "-" else (.[0].mean_position_mm * 1000 | round / 1000 | tostring) end' "$1"
}
rows() {
  jq -r --arg m "$2" --arg s "$3" \
    '[.[] | select(.method == $m and ($s == "" or .set == $s))] | if length == 0 then 0 else .[0].rows end' "$1"
}

table=$out/table.md
{
  echo "| case | rows | geometric (poe) | extended | extended+GPR | covered rows | geometric, covered | extended, covered |"
  echo "|---|---|---|---|---|---|---|---|"
} >"$table"
for case in C-split:C-split A-split:A-split A:D A:B B:C C:D; do
  src=${case%%:*}
  tgt=${case#*:}
  if [[ $src == "$tgt" ]]; then
    flags=() set=validation suffix="" name="${src%-split}→${src%-split}, rows from ${split[${src%-split}]} on"
  else
    flags=(--refit-frames) set="" suffix=" (frames refit)" name="$src→$tgt (frames refitted on $tgt)"
  fi
  "$bin/stepcal" validate "$out/$src.poe.stepcal" "$out/$tgt" "${flags[@]}" --json >"$out/$src-$tgt.poe.json"
  "$bin/stepcal" validate "$out/$src.extended.stepcal" "$out/$tgt" "${flags[@]}" --json \
    >"$out/$src-$tgt.extended.json"
  g=$(mean "$out/$src-$tgt.poe.json" "poe$suffix" "$set")
  e=$(mean "$out/$src-$tgt.extended.json" "extended$suffix" "$set")
  eg=$(mean "$out/$src-$tgt.extended.json" "extended+gpr$suffix" "$set")
  n=$(rows "$out/$src-$tgt.extended.json" "extended$suffix" "$set")
  nc=$(rows "$out/$src-$tgt.extended.json" "extended$suffix (covered rows)" "$set")
  # The geometric model on the rows the extended model covers.
  "$bin/stepcal" validate "$out/$src.poe.stepcal" "$out/$tgt" "${flags[@]}" --json \
    --rows-covered-by "$out/$src.extended.stepcal" >"$out/$src-$tgt.poe-covered.json"
  gc=$(mean "$out/$src-$tgt.poe-covered.json" "poe$suffix (covered rows)" "$set")
  ec=$(mean "$out/$src-$tgt.extended.json" "extended$suffix (covered rows)" "$set")
  echo "| $name | $n | $g | $e | $eg | $nc | $gc | $ec |" >>"$table"
done
cat "$table"
echo "diagnosis wall time (s): $(for s in A B C A-split C-split; do printf '%s %s  ' "$s" "$(cat "$out/$s.seconds")"; done)"
