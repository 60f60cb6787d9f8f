#!/usr/bin/env bash
# Prints one row of a campaign's measurements.csv as the consumer's arguments, SI:
# q1..q6 (rad) fx fy fz mx my mz (N, N·m) x y z (m) — the first loaded validation row.
#   tests/system/campaign_row.sh CAMPAIGN_DIR
set -euo pipefail
awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) col[$i] = i; next }
  $col["set"] == "validation" && $col["load_kg"] > 0 {
    pi = 3.141592653589793
    for (j = 1; j <= 6; j++) printf "%.17g ", $col["q" j "_deg"] * pi / 180
    split("fx_n fy_n fz_n mx_nm my_nm mz_nm", w, " ")
    for (j = 1; j <= 6; j++) printf "%.17g ", $col[w[j]]
    printf "%.17g %.17g %.17g\n", $col["x_mm"] / 1000, $col["y_mm"] / 1000, $col["z_mm"] / 1000
    exit
  }' "$1/measurements.csv"
