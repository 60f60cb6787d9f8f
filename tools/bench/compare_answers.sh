#!/bin/sh
# Compares two `stepcal-bench --answers` files of the same model (two builds): the largest
# difference of the forward positions (m) and rotation entries, of the inverse joint targets
# (rad) and residuals, and the poses whose statuses or iteration counts differ.
#   tools/bench/compare_answers.sh BEFORE.csv AFTER.csv
set -eu
[ $# -eq 2 ] || { echo "usage: $0 BEFORE.csv AFTER.csv" >&2; exit 2; }
awk -F, '
  function abs(x) { return x < 0 ? -x : x }
  FNR == 1 { for (i = 1; i <= NF; ++i) col[$i] = i; next }
  NR == FNR { for (i = 1; i <= NF; ++i) before[FNR, i] = $i; rows = FNR; next }
  {
    if (!((FNR, 1) in before)) { print "pose " $1 ": only in the second file"; bad = 1; next }
    for (i = 1; i <= NF; ++i) {
      b = before[FNR, i]; a = $i
      if (i == col["forward_status"] || i == col["inverse_status"]) {
        if (a != b) { status_diff++; if (status_diff <= 5) print "pose " $1 ": " b " -> " a }
      } else if (i == col["iterations"]) {
        if (a != b) iteration_diff++
        iterations_before += b; iterations_after += a
      } else if (i >= col["x_m"] && i <= col["z_m"]) {
        d = abs(a - b); if (d > position_m) position_m = d
      } else if (i >= col["r0"] && i <= col["r8"]) {
        d = abs(a - b); if (d > rotation) rotation = d
      } else if (i >= col["q1_rad"] && i < col["residual_position_m"]) {
        d = abs(a - b); if (d > joint_rad) joint_rad = d
      } else if (i == col["residual_position_m"]) {
        if (a > worst_residual_m) worst_residual_m = a
      }
    }
    compared++
  }
  END {
    printf "poses compared %d (first file %d)\n", compared, rows
    printf "forward: largest position difference %.3g m, rotation entry %.3g\n", position_m, rotation
    printf "inverse: largest joint target difference %.3g rad; statuses differing %d; iteration counts differing %d (mean %.3f -> %.3f); largest residual after %.3g m\n", \
      joint_rad, status_diff, iteration_diff, iterations_before / compared, iterations_after / compared, worst_residual_m
    exit bad
  }' "$1" "$2"
