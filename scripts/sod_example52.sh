#!/usr/bin/env bash
# Example 5.2 of the send-on-delta co-design paper: PI on the last received measurement vs
# inferential PI on the send-on-delta observer (DC motor over CAN). One traced run each;
# table.csv (tracking error, limit cycle, transmissions) and fig6.svg (gnuplot).
#   scripts/sod_example52.sh [OUT]   (default results/sod_example52; binary: $NCOSIM or build/sim/ncosim)
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${NCOSIM:-build/sim/ncosim}
OUT=${1:-results/sod_example52}
SC=scenarios/sod_example52.toml
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
mkdir -p "$OUT"
TABLE="$TMP/table.csv"
echo "feedback,tracking_rmse,steady_error_percent,limit_cycle_u_p2p,limit_cycle_y_p2p,sent_per_period,estimator_mse,estimator_status" > "$TABLE"
for fb in received sod_jump; do
  "$BIN" run "$SC" --quiet --trace --out "$TMP/$fb" --set "input.feedback=\"$fb\"" > /dev/null
  cp "$TMP/$fb/trajectory.csv" "$OUT/trajectory_$fb.csv"
  # After the first second: RMS of r - y; in the last 0.25 s of each half period (steady
  # state), mean |r - y| / r in %, and the mean peak-to-peak of u and of y (limit cycle).
  metrics=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) c[$i] = i; next }
    { k = $1; if (k < 200) next; r = $c["reference"]; y = $c["y:speed"]; u = $c["u1"];
      se += (r - y)^2; n++;
      ph = k % 100; w = int(k / 100);
      if (ph >= 50) { if (!(w in umin) || u < umin[w]) umin[w] = u; if (!(w in umax) || u > umax[w]) umax[w] = u;
                      if (!(w in ymin) || y < ymin[w]) ymin[w] = y; if (!(w in ymax) || y > ymax[w]) ymax[w] = y;
                      ae += (r > y ? r - y : y - r) / r; na++ } }
    END { for (w in umin) { up += umax[w] - umin[w]; yp += ymax[w] - ymin[w]; nw++ }
          printf "%.6g,%.6g,%.6g,%.6g", sqrt(se / n), 100 * ae / na, up / nw, yp / nw }' "$TMP/$fb/trajectory.csv")
  est=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) c[$i] = i } NR > 1 && $1 == "sod_jump" { print $c["sent_per_period"] "," $c["mse"] "," $c["status"] }' "$TMP/$fb/summary.csv")
  echo "$fb,$metrics,$est" >> "$TABLE"
done
cp "$TABLE" "$OUT/table.csv"
cp "$TMP/received/manifest.json" "$OUT/manifest.json"
cp "$TMP/received/design.json" "$OUT/design.json"
gnuplot -e "dir='$OUT'" scripts/sod_example52.gp
column -s, -t "$OUT/table.csv" >&2
