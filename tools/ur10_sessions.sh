#!/usr/bin/env bash
# The real UR10, leave one series out (README, "Several campaigns of one robot"): three of the four
# series fitted together, one robot with each series its own tracker registration and tool, as the
# geometric model (`stepcal calibrate X Y Z`) and as the extended model (`stepcal diagnose X Y Z`),
# both validated on the fourth with the tracker and tool frames fitted again there (`stepcal
# validate --refit-frames`). Beside them, the best of the three series' own models validated the
# same way. Mean position error, mm, on all rows of the left-out series and on the rows whose joint
# angles every transmission profile of the extended model covers.
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
# An independent analysis of the same data (three series jointly, harmonics up to 24 gated by the
# union's coverage), mean mm on all rows of the left-out series: the figures to beat.
declare -A independent=([A]=0.192 [B]=0.235 [C]=0.497 [D]=0.321)

# The geometric model (calibrate) and the extended model (diagnose) of a list of series, once.
models() {
  local tag=$1
  shift
  [[ -f $out/$tag.poe.stepcal ]] || "$bin/stepcal" calibrate "${@/#/$out/}" --out "$out/$tag.poe.stepcal" >/dev/null
  if [[ ! -f $out/$tag.extended.stepcal ]]; then
    /usr/bin/time -f "%e s, %M kB" -o "$out/$tag.cost" "$bin/stepcal" diagnose "${@/#/$out/}" \
      --model "$out/$tag.poe.stepcal" --out "$out/$tag.extended.stepcal" --json >"$out/$tag.diagnosis.json"
  fi
}

# mean position error (mm) of a method in a validate JSON, or "-"; rows of it
mean() {
  jq -r --arg m "$2" '[.[] | select(.method == $m)] |
    if length == 0 then "-" else (.[0].mean_position_mm * 1000 | round / 1000 | tostring) end' "$1"
}
rows() {
  jq -r --arg m "$2" '[.[] | select(.method == $m)] | if length == 0 then 0 else .[0].rows end' "$1"
}
# the smaller of two figures, "-" counting as none
smaller() {
  if [[ $1 == - ]]; then echo "$2"; elif [[ $2 == - ]] || awk -v a="$1" -v b="$2" 'BEGIN { exit !(a < b) }'; then
    echo "$1"; else echo "$2"; fi
}

for s in A B C D; do
  [[ -f $out/$s/campaign.yaml ]] || "$bin/stepcal" import ipa "$data/${csv[$s]}" --out "$out/$s" >/dev/null
  models "$s" "$s"
done

table=$out/table.md
{
  echo "| left out | rows | fitted on | geometric, three together | extended, three together | extended+GPR | covered rows | geometric, covered | extended, covered | best single series: geometric | extended | independent analysis |"
  echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
} >"$table"
for left in A B C D; do
  others=()
  for s in A B C D; do [[ $s == "$left" ]] || others+=("$s"); done
  tag=$(IFS=; echo "${others[*]}")
  models "$tag" "${others[@]}"
  "$bin/stepcal" validate "$out/$tag.poe.stepcal" "$out/$left" --refit-frames --json \
    --rows-covered-by "$out/$tag.extended.stepcal" >"$out/$tag-$left.poe.json"
  "$bin/stepcal" validate "$out/$tag.extended.stepcal" "$out/$left" --refit-frames --json \
    >"$out/$tag-$left.extended.json"
  g=$(mean "$out/$tag-$left.poe.json" "poe (frames refit)")
  gc=$(mean "$out/$tag-$left.poe.json" "poe (frames refit) (covered rows)")
  e=$(mean "$out/$tag-$left.extended.json" "extended (frames refit)")
  eg=$(mean "$out/$tag-$left.extended.json" "extended+gpr (frames refit)")
  ec=$(mean "$out/$tag-$left.extended.json" "extended (frames refit) (covered rows)")
  n=$(rows "$out/$tag-$left.extended.json" "extended (frames refit)")
  nc=$(rows "$out/$tag-$left.extended.json" "extended (frames refit) (covered rows)")
  best_g=- best_e=-
  for s in "${others[@]}"; do
    "$bin/stepcal" validate "$out/$s.poe.stepcal" "$out/$left" --refit-frames --json >"$out/$s-$left.poe.json"
    "$bin/stepcal" validate "$out/$s.extended.stepcal" "$out/$left" --refit-frames --json \
      >"$out/$s-$left.extended.json"
    best_g=$(smaller "$best_g" "$(mean "$out/$s-$left.poe.json" "poe (frames refit)")")
    best_e=$(smaller "$best_e" "$(mean "$out/$s-$left.extended.json" "extended (frames refit)")")
  done
  echo "| $left | $n | ${others[*]} | $g | $e | $eg | $nc | $gc | $ec | $best_g | $best_e | ${independent[$left]} |" >>"$table"
done
cat "$table"
echo "diagnosis of three series (wall time, peak memory): $(for t in BCD ACD ABD ABC; do printf '%s %s;  ' "$t" "$(cat "$out/$t.cost")"; done)"
