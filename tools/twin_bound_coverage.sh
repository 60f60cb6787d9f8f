#!/usr/bin/env bash
# The stated 95 % position bound judged on the twin over many seeds (docs/method.md, "The
# accuracy bound"): per seed, `stepcal simulate`, `stepcal calibrate` (the paper's three steps)
# and `stepcal diagnose` (the extended model), then `stepcal validate --json --bound-coverage` of
# each model; the held-out validation rows (and the rows outside the calibrated region) pooled
# over the seeds per load: rows, rows covered, % with its Wilson 95 % interval, mean bound and
# error.
#
# Usage: tools/twin_bound_coverage.sh [SEEDS [OUT]]
#   SEEDS  the seeds, e.g. "$(seq 1 20)" (default 1 … 20)
#   OUT    working folder (default out/twin-bound-coverage); the table also goes to OUT/table.md
# A campaign other than the twin's (e.g. a foreign-effect stress seed) is judged the same way with
#   STEPCAL_CAMPAIGNS="DIR …" tools/twin_bound_coverage.sh "" OUT   (the campaigns instead of seeds)
# Environment: STEPCAL_BIN_DIR (default build/bin).
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
seeds=${1:-$(seq 1 20)}
out=${2:-$root/out/twin-bound-coverage}
bin=${STEPCAL_BIN_DIR:-$root/build/bin}
command -v jq >/dev/null || { echo "twin_bound_coverage: needs jq (apt-get install jq)" >&2; exit 2; }
mkdir -p "$out"

campaigns=()
if [[ -n ${STEPCAL_CAMPAIGNS:-} ]]; then
  for dir in $STEPCAL_CAMPAIGNS; do campaigns+=("$(realpath "$dir")"); done
else
  for seed in $seeds; do
    [[ -f $out/seed-$seed/campaign.yaml ]] ||
      "$bin/stepcal" simulate --seed "$seed" --out "$out/seed-$seed" >/dev/null
    campaigns+=("$out/seed-$seed")
  done
fi

# Per campaign: both models, both validated (one JSON line per model and group of rows).
: >"$out/coverage.jsonl"
for dir in "${campaigns[@]}"; do
  name=$(basename "$dir")
  "$bin/stepcal" calibrate "$dir" --out "$out/$name.paper.stepcal" >/dev/null
  "$bin/stepcal" diagnose "$dir" --model "$out/$name.paper.stepcal" \
    --out "$out/$name.extended.stepcal" >/dev/null
  for model in paper extended; do
    "$bin/stepcal" validate "$out/$name.$model.stepcal" "$dir" --json --bound-coverage |
      jq -c --arg model "$model" --arg campaign "$name" \
        '.bound_coverage[] | select(.group == "validation" or .group == "outside")
         | . + {model: $model, campaign: $campaign,
                covered: ((.position_coverage_pct * .rows / 100) | round)}' >>"$out/coverage.jsonl"
  done
done

# Pooled per model, group and load; Wilson's 95 % interval of the covered fraction.
{
  echo "| model | rows | load kg | rows | covered | % (Wilson 95 %) | mean bound mm | mean error mm |"
  echo "|---|---|---|---|---|---|---|---|"
  jq -s -r 'group_by([.model, .group, .load_kg])[]
    | {model: .[0].model, group: .[0].group, load: .[0].load_kg,
       n: (map(.rows) | add), k: (map(.covered) | add),
       bound: ((map(.mean_bound_mm * .rows) | add) / (map(.rows) | add)),
       error: ((map(.mean_error_mm * .rows) | add) / (map(.rows) | add))}
    | [.model, .group, (if .load < 0 then "all" else .load end), .n, .k, .bound, .error] | @tsv' \
    "$out/coverage.jsonl" | sort -t$'\t' -k1,1r -k2,2r -k3,3n |
    awk -F'\t' '{
      n = $4; k = $5; p = k / n; z = 1.959964; d = 1 + z*z/n;
      c = (p + z*z/(2*n)) / d; h = z * sqrt(p*(1-p)/n + z*z/(4*n*n)) / d;
      printf "| %s | %s | %s | %d | %d | %.1f (%.1f–%.1f) | %.4f | %.4f |\n",
             $1, $2, $3, n, k, 100*p, 100*(c-h), 100*(c+h), $6, $7 }'
} | tee "$out/table.md"
