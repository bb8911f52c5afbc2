#!/bin/sh
# results/schenato2008_fig6/make_fig6.sh — regenerates Fig. 6 of Schenato (2008) (left: motor,
# right: pendulum). Run from the repository root after building: sh results/schenato2008_fig6/make_fig6.sh [NCOSIM]
# Needs jq and gnuplot. Writes motor/ and pendulum/ (the ncosim result sets), fig6_motor.csv,
# fig6_pendulum.csv, fig6.png and fig6.svg.
set -eu
NCOSIM=${1:-build/sim/ncosim}
OUT=results/schenato2008_fig6
for ex in motor pendulum; do
  "$NCOSIM" run "scenarios/schenato2008_$ex.toml" --out "$OUT/$ex" --quiet --replace
  # Ideal network (every sample at delay 0): the static design with N = 1 and lambda_0 = 1 is the
  # stationary Kalman filter.
  "$NCOSIM" design "scenarios/schenato2008_$ex.toml" --out "$OUT/$ex/ideal" \
    --set 'link[0].cdf=[1.0]' --set 'link[0].tail=1.0'
  ideal=$(jq -r '.estimators[0] | "\(.trace_V0),\(.predicted_mse)"' "$OUT/$ex/ideal/design.json")
  {
    echo "N,trace_V0_static,predicted_mse_static,trace_V0_ideal,predicted_mse_ideal,mse_static,mse_static_ci95,mse_optimal,mse_optimal_ci95,status_static,status_optimal"
    for N in $(seq 1 16); do
      d=$(jq -r --arg n "static N=$N" '.estimators[] | select(.name == $n) | "\(.trace_V0 // ""),\(.predicted_mse // "")"' "$OUT/$ex/design.json")
      s=$(awk -F, -v n="static N=$N" '$1 == n { printf "%s,%s,%s", $4, $5, $16 }' "$OUT/$ex/summary.csv")
      o=$(awk -F, -v n="optimal N=$N" '$1 == n { printf "%s,%s,%s", $4, $5, $16 }' "$OUT/$ex/summary.csv")
      ms=$(echo "$s" | cut -d, -f1,2); ss=$(echo "$s" | cut -d, -f3)
      mo=$(echo "$o" | cut -d, -f1,2); so=$(echo "$o" | cut -d, -f3)
      echo "$N,$d,$ideal,$ms,$mo,$ss,$so"
    done
  } > "$OUT/fig6_$ex.csv"
done
for term in "pngcairo size 1400,560 font ',11'" "svg size 1400,560 font ',11'"; do
  ext=$(echo "$term" | cut -c1-3 | sed 's/png/png/;s/svg/svg/')
  gnuplot <<GP
set terminal $term
set output "$OUT/fig6.$ext"
set datafile separator ","
set key top right
set xlabel "buffer length N"
set ylabel "error covariance trace"
set xrange [0.5:16.5]
set grid
set multiplot layout 1,2 title "Schenato (2008) Fig. 6: static-gain and optimal buffered estimators (lambda_h = 0.05 h, 25 % lost)"
do for [ex in "motor pendulum"] {
  f = sprintf("$OUT/fig6_%s.csv", ex)
  set title ex
  if (ex eq "motor") { set yrange [0:16] } else { set yrange [0:80] }
  plot f u 1:2 w lp pt 7 lc rgb "#1f77b4" t "tr V_0^N static (paper's quantity, predicted)", \
       f u 1:3 w lp pt 5 lc rgb "#2ca02c" t "static filtered, predicted", \
       f u 1:4 w l dt 2 lc rgb "#7f7f7f" t "ideal network tr V_0", \
       f u 1:5 w l dt 3 lc rgb "#7f7f7f" t "ideal network filtered", \
       f u (\$1-0.12):6:7 w yerrorbars pt 4 lc rgb "#d62728" t "static simulated (95 % CI)", \
       f u (\$1+0.12):8:9 w yerrorbars pt 6 lc rgb "#9467bd" t "kalman\\\_buffer simulated (95 % CI)"
}
unset multiplot
GP
done
