#!/usr/bin/env bash
# Example 5.1 of the send-on-delta co-design paper: for each mu and each case (C1-C4 and the
# beta = beta'-only variant of C3), co-design the thresholds (`ncosim codesign`), then simulate
# the scenario at them (`ncosim run`) and collect one CSV row; then the Suh et al. comparison
# at mu = 1.2 and the gnuplot figures. Needs jq and gnuplot.
#   scripts/sod_example51.sh [OUT]   (default results/sod_example51; binary: $NCOSIM or build/sim/ncosim)
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${NCOSIM:-build/sim/ncosim}
OUT=${1:-results/sod_example51}
SC=scenarios/sod_example51.toml
MUS=${MUS:-"1.05 1.1 1.2 1.4 1.6 1.8 2 2.25 2.5 2.75 3"}
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
mkdir -p "$OUT"
CSV="$TMP/sweep.csv"
echo "case,mu,z0,target,epsilon,step,delta0_1,delta0_2,delta1,delta2,cost,guaranteed_bound,lmi_problems,lmi_seconds,codesign_seconds,simulated_mse,simulated_mse_ci95,sent_per_period,beta1_sim,beta2_sim,virtual_rms1_sim,virtual_rms2_sim,status" > "$CSV"
for mu in $MUS; do
  for est in C1 C2 C3 C4 C3_lower; do
    "$BIN" codesign "$SC" --estimator "$est" --mu "$mu" --out "$TMP/cd" --quiet > /dev/null
    J="$TMP/cd/codesign.json"
    d1=$(jq -r '.[0].delta[0]' "$J"); d2=$(jq -r '.[0].delta[1]' "$J")
    "$BIN" run "$SC" --quiet --replace --out "$TMP/run" --set "sensor[0].delta=$d1" --set "sensor[1].delta=$d2" > /dev/null
    row=$(awk -F, -v e="$est" 'NR == 1 { for (i = 1; i <= NF; ++i) c[$i] = i } NR > 1 && $1 == e { print $c["mse"] "," $c["mse_ci95"] "," $c["sent_per_period"] "," $c["status"] }' "$TMP/run/summary.csv")
    IFS=, read -r mse ci spp status <<< "$row"
    b1=$(awk -F, 'NR == 2 { print $7 }' "$TMP/run/transmissions.csv"); b2=$(awk -F, 'NR == 3 { print $7 }' "$TMP/run/transmissions.csv")
    v1=$(awk -F, 'NR == 2 { print $8 }' "$TMP/run/transmissions.csv"); v2=$(awk -F, 'NR == 3 { print $8 }' "$TMP/run/transmissions.csv")
    jq -r --arg est "$est" --arg mse "$mse" --arg ci "$ci" --arg spp "$spp" --arg b1 "$b1" --arg b2 "$b2" --arg v1 "$v1" --arg v2 "$v2" --arg st "$status" \
      '.[0] | [$est, .mu, .z0, .target, .epsilon, .step, .delta0[0], .delta0[1], .delta[0], .delta[1], .cost, .bound, .lmi_problems, .lmi_seconds, .seconds, $mse, $ci, $spp, $b1, $b2, $v1, $v2, (if .status == "ok" then $st else .status end)] | @csv' "$J" | tr -d '"' >> "$CSV"
    echo "mu $mu $est: delta [$d1 $d2] mse $mse sent/period $spp" >&2
  done
done
# Suh et al. (2007) at the paper's thresholds: W = 0.1 I with Delta = [0.9 0.5], W = 0.02 I
# with the C3 (mu = 1.2) thresholds of the paper, [0.236 0.098].
SUH="$TMP/suh.csv"
echo "filter_W,delta1,delta2,simulated_mse,simulated_mse_ci95,sent_per_period,paper" > "$SUH"
for spec in "0.1 0.9 0.5 0.4174" "0.02 0.236 0.098 1.5*z0"; do
  read -r w d1 d2 paper <<< "$spec"
  "$BIN" run "$SC" --quiet --replace --out "$TMP/suh" --set "sensor[0].delta=$d1" --set "sensor[1].delta=$d2" --set "estimator[0].W=$w" > /dev/null
  awk -F, -v w="$w" -v d1="$d1" -v d2="$d2" -v p="$paper" 'NR == 1 { for (i = 1; i <= NF; ++i) c[$i] = i } NR > 1 && $2 == "sod_kalman" { print w "," d1 "," d2 "," $c["mse"] "," $c["mse_ci95"] "," $c["sent_per_period"] "," p }' "$TMP/suh/summary.csv" >> "$SUH"
done
cp "$CSV" "$OUT/sweep.csv"
cp "$SUH" "$OUT/suh_comparison.csv"
"$BIN" run "$SC" --quiet --out "$TMP/ref" > /dev/null
cp "$TMP/ref/manifest.json" "$OUT/manifest.json"
gnuplot -e "dir='$OUT'" scripts/sod_example51.gp
echo "results in $OUT/" >&2
