#!/usr/bin/env bash
# Does a fitted channel predict estimator performance? The SUMO beacon scenario
# (scenarios/sumo_beacons.toml: 4 receivers x 3 channel presets, 40 runs x 2000 periods, run r on
# mobility realisation r mod 4) is run as committed ("sumo"), its V2V link is recorded packet by
# packet (`ncosim record-link`: one trace per case, the 40 runs one after the other), the scored
# part of each trace (periods >= warmup, the 40 runs concatenated: 62 000 packets) is fitted
# (`ncosim fit`: Bernoulli and hidden two-state Gilbert-Elliott), and the same estimators run on
#   trace      the record replayed, run r its own packets (`trace` link, `segment` = periods):
#              for kalman_extended the SUMO campaign's errors, run by run
#   scored     the same with the warm-up rows (k < warmup) delivered: the scored periods replay
#              the record exactly, and no observer starts from the receiver's absence (the
#              reference of the models below; see results/channel_study/README.md)
#   ge         the fitted Gilbert-Elliott link
#   bernoulli  a Bernoulli link with the trace's mean loss (the Bernoulli fit)
# with the same seeds (same mobility realisation and measurement noise in run r of every variant).
# Writes OUT/table.csv, table.md, fits.csv, realisations.csv, tails.csv, mse_ratio.{dat,gp,png,svg}
# and the five campaigns'
# summary_<variant>.csv; the generated traces, fits, scenarios and campaigns stay in WORK.
# Needs gnuplot, awk and the SUMO inputs (built here if missing). About 15 s of 2 cores.
#   scripts/channel_study.sh [OUT]   (default results/channel_study; binary: $NCOSIM or build/sim/ncosim;
#                                      WORK: $WORK or out/channel_study)
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
BIN=${NCOSIM:-build/sim/ncosim}
case "$BIN" in /*) ;; *) BIN="$ROOT/$BIN" ;; esac
OUT=${1:-results/channel_study}
WORK=${WORK:-out/channel_study}
SC=scenarios/sumo_beacons.toml
[ -f scenarios/sumo/gen/highway.net.xml ] || sh scenarios/sumo/make_inputs.sh
rm -rf "$WORK"
mkdir -p "$WORK" "$OUT"
WARMUP=$(awk '$1 == "warmup" { print $3 }' "$SC")
PERIODS=$(awk '$1 == "periods" { print $3 }' "$SC")
RUNS=$(awk '$1 == "runs" { print $3; exit }' "$SC")

echo "1/5 the SUMO campaign and its link's record" >&2
"$BIN" run "$SC" --out "$WORK/sumo" --quiet --no-timing > /dev/null
"$BIN" record-link "$SC" --link v2v --out "$WORK/record" --quiet > /dev/null
mkdir -p "$WORK/scored"
for f in "$WORK"/record/v2v_case*.csv; do
  awk -F, -v w="$WARMUP" -v p="$PERIODS" 'NR == 1 || $1 % p >= w { print; next } { print $1 ",0" }' "$f" \
    > "$WORK/scored/$(basename "$f")"
done

echo "2/5 fits of the scored periods (k >= $WARMUP) of every run" >&2
# fits.csv: case, receiver, preset, packets, loss, trace mean loss run, trace longest loss run,
# the GE parameters with their 95 % intervals, the GE bad state's mean sojourn (1 / p_bad_to_good),
# BIC of both, burst_tv and acf_rmse of both.
FITS="$WORK/fits.csv"
echo "case,receiver,preset,packets,loss,loss_ci95_low,loss_ci95_high,trace_burst_mean,trace_burst_max,ge_p_good_to_bad,ge_p_good_to_bad_ci95_low,ge_p_good_to_bad_ci95_high,ge_p_bad_to_good,ge_p_bad_to_good_ci95_low,ge_p_bad_to_good_ci95_high,ge_loss_good,ge_loss_good_ci95_low,ge_loss_good_ci95_high,ge_loss_bad,ge_loss_bad_ci95_low,ge_loss_bad_ci95_high,ge_bad_sojourn,bic_bernoulli,bic_ge,burst_tv_bernoulli,burst_tv_ge,acf_rmse_bernoulli,acf_rmse_ge" > "$FITS"
tail -n +2 "$WORK/record/record.csv" | while IFS=, read -r receiver preset _link file _rest; do
  c=${file#v2v_case}; c=${c%.csv}
  scored="$WORK/fit/scored_$c.csv"
  mkdir -p "$WORK/fit"
  # The scored rows, renumbered; the loss runs counted within each run (a run's end closes one).
  stats=$(awk -F, -v w="$WARMUP" -v p="$PERIODS" -v out="$scored" '
    BEGIN { print "seq,delay" > out; n = 0 }
    NR > 1 {
      k = $1 % p
      if (k < w) next
      print n "," $2 > out; ++n
      if (k == w && open > 0) { runs++; sum += open; if (open > mx) mx = open; open = 0 }
      if ($2 == "") open++; else if (open > 0) { runs++; sum += open; if (open > mx) mx = open; open = 0 }
    }
    END { if (open > 0) { runs++; sum += open; if (open > mx) mx = open }
          printf "%s,%s", (runs ? sum / runs : ""), (runs ? mx : 0) }' "$WORK/record/$file")
  "$BIN" fit "$scored" --family bernoulli --family gilbert_elliott --out "$WORK/fit/fit_$c" > /dev/null
  awk -F, -v c="$c" -v r="$receiver" -v pr="$preset" -v st="$stats" '
    { v[$1 "," $2 "," $3] = $4; lo[$1 "," $2 "," $3] = $5; hi[$1 "," $2 "," $3] = $6 }
    function tri(key) { return v[key] "," lo[key] "," hi[key] }
    END {
      g = "gilbert_elliott,parameter,"
      print c "," r "," pr "," v["bernoulli,fit,packets"] "," tri("bernoulli,parameter,loss") "," st "," \
        tri(g "p_good_to_bad") "," tri(g "p_bad_to_good") "," tri(g "loss_good") "," tri(g "loss_bad") "," \
        (v[g "p_bad_to_good"] > 0 ? 1 / v[g "p_bad_to_good"] : "") "," \
        v["bernoulli,fit,bic"] "," v["gilbert_elliott,fit,bic"] "," \
        v["bernoulli,fit,burst_tv"] "," v["gilbert_elliott,fit,burst_tv"] "," \
        v["bernoulli,fit,acf_rmse"] "," v["gilbert_elliott,fit,acf_rmse"]
    }' "$WORK/fit/fit_$c/fit.csv" >> "$FITS"
done

echo "3/5 the variant scenarios" >&2
# Each variant: the committed scenario up to its [[link]] (the [sumo] paths made absolute, the
# scenario moving to WORK), its own [[link]] table, the committed sensors and estimators, and one
# zipped sweep axis over the 12 cases in record.csv's order.
head_part() {
  awk '/^\[\[link\]\]/ { exit } { print }' "$SC" | sed "s|= \"sumo/gen/|= \"$ROOT/scenarios/sumo/gen/|"
}
body_part() {
  awk '/^\[\[sensor\]\]/ { on = 1 } /^\[\[sweep\]\]/ { on = 0 } on { print }' "$SC"
}
list() {  # list COLUMN [quote]: the fits.csv column as a TOML array
  awk -F, -v col="$1" -v q="${2:-}" 'NR == 1 { for (i = 1; i <= NF; ++i) if ($i == col) k = i; next }
    { printf "%s%s%s%s", (NR > 2 ? ", " : "["), q, $k, q } END { print "]" }' "$FITS"
}
files=$(awk -F, 'NR > 1 { printf "%s\"record/%s\"", (NR > 2 ? ", " : "["), $4 } END { print "]" }' "$WORK/record/record.csv")
{
  head_part
  printf '[[link]]\nname = "v2v"\nkind = "trace"\nfile = "record/v2v_case0.csv"\nsegment = %s\n\n' "$PERIODS"
  body_part
  printf '[[sweep]]\nkey = "link[0].file"\nvalues = %s\n' "$files"
} > "$WORK/trace.toml"
sed 's|"record/v2v_case|"scored/v2v_case|g' "$WORK/trace.toml" > "$WORK/scored.toml"
{
  head_part
  printf '[[link]]\nname = "v2v"\nkind = "gilbert_elliott"\np_good_to_bad = 0.1\np_bad_to_good = 0.1\n\n'
  body_part
  for key in p_good_to_bad p_bad_to_good loss_good loss_bad; do
    printf '[[sweep]]\nkey = "link[0].%s"\nvalues = %s\nzip = "case"\n\n' "$key" "$(list "ge_$key")"
  done
} > "$WORK/ge.toml"
{
  head_part
  printf '[[link]]\nname = "v2v"\nkind = "bernoulli"\n\n'
  body_part
  printf '[[sweep]]\nkey = "link[0].loss"\nvalues = %s\n' "$(list loss)"
} > "$WORK/bernoulli.toml"

echo "4/5 the four campaigns" >&2
for v in trace scored ge bernoulli; do
  "$BIN" run "$WORK/$v.toml" --out "$WORK/$v" --quiet --no-timing > /dev/null
done

echo "5/5 table and figure" >&2
# Per (case, estimator) and variant: mse and its 95 % CI (summary.csv), the delivered ratio, and
# against the trace replay on the same runs: ratio mean(mse_V) / mean(mse_trace) with the delta
# method's 95 % half-width (z_r = (b_r - ratio a_r) / mean(a), t_{0.975, R-1} sd(z) / sqrt(R)).
per_run() {  # per_run VARIANT: case_index,estimator,run,mse (cases numbered in order of appearance)
  awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) c[$i] = i; next }
    { key = ""; for (i = 1; i < c["run"]; ++i) key = key $i ","
      if (!(key in idx)) idx[key] = n++
      print idx[key] "," $c["estimator"] "," $c["run"] "," $c["mse"] }' "$WORK/$1/runs.csv"
}
summ() {  # summ VARIANT: case_index,estimator,mse,mse_ci95,delivered
  awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) c[$i] = i; next }
    { key = ""; for (i = 1; i < c["estimator"]; ++i) key = key $i ","
      if (!(key in idx)) idx[key] = n++
      print idx[key] "," $c["estimator"] "," $c["mse"] "," $c["mse_ci95"] "," $c["delivered_ratio"] }' "$WORK/$1/summary.csv"
}
VARIANTS="sumo trace scored ge bernoulli"
for v in $VARIANTS; do
  per_run "$v" > "$WORK/per_run_$v.csv"
  summ "$v" > "$WORK/summ_$v.csv"
  cp "$WORK/$v/summary.csv" "$OUT/summary_$v.csv"
done
# The record is the campaign's channel: kalman_extended (no design law) has the same per-run MSE
# under the replayed record as under the live link, run by run.
same=$(awk -F, '$2 == "kalman_extended"' "$WORK/per_run_sumo.csv" | cmp -s - <(awk -F, '$2 == "kalman_extended"' "$WORK/per_run_trace.csv") && echo yes || echo no)
echo "kalman_extended per-run mse identical under the live link and the replayed record: $same" >&2
echo "$same" > "$WORK/replay_identical"
TABLE="$OUT/table.csv"
# Variants 0..4 as in VARIANTS; the reference of the ratios is 2 (scored).
awk -F, -v R="$RUNS" -v ref=2 '
  function t975(df) { return df >= 120 ? 1.98 : (df >= 60 ? 2.0 : (df >= 39 ? 2.0227 : 2.0452)) }
  FNR == 1 { ++f }
  f == 1 && FNR > 1 { rec[FNR - 2] = $1 "," $2; next }           # record.csv: receiver,preset
  f == 2 && FNR > 1 { fit[$1] = $5 "," $8 "," $22; next }         # fits.csv: loss, trace mean loss run, GE bad sojourn
  f >= 3 && f <= 7 { v = f - 3; s[v, $1, $2] = $3 "," $4; d[v, $1, $2] = $5; if (v == 0) order[++m] = $1 SUBSEP $2; next }
  f >= 8 { v = f - 8; x[v, $1, $2, $3] = $4 }
  END {
    print "receiver,preset,estimator,trace_loss,trace_burst_mean,ge_bad_sojourn," \
      "delivered_sumo,delivered_trace,delivered_scored,delivered_ge,delivered_bernoulli," \
      "mse_sumo,mse_sumo_ci95,mse_trace,mse_trace_ci95,mse_scored,mse_scored_ci95,mse_ge,mse_ge_ci95,mse_bernoulli,mse_bernoulli_ci95," \
      "ratio_trace,ratio_trace_ci95,ratio_ge,ratio_ge_ci95,ratio_bernoulli,ratio_bernoulli_ci95"
    for (i = 1; i <= m; ++i) {
      split(order[i], ce, SUBSEP); c = ce[1]; e = ce[2]
      if (e == "open_loop") continue
      line = rec[c] "," e "," fit[c]
      for (v = 0; v <= 4; ++v) line = line "," d[v, c, e]
      for (v = 0; v <= 4; ++v) line = line "," s[v, c, e]
      for (v = 1; v <= 4; ++v) {
        if (v == ref) continue
        ma = 0; mb = 0
        for (r = 0; r < R; ++r) { ma += x[ref, c, e, r]; mb += x[v, c, e, r] }
        ma /= R; mb /= R
        if (ma <= 0) { line = line ",,"; continue }
        q = mb / ma; sz = 0; szz = 0
        for (r = 0; r < R; ++r) { z = (x[v, c, e, r] - q * x[ref, c, e, r]) / ma; sz += z; szz += z * z }
        sd = sqrt((szz - sz * sz / R) / (R - 1))
        line = line sprintf(",%.6g,%.6g", q, t975(R - 1) * sd / sqrt(R))
      }
      print line
    }
  }' "$WORK/record/record.csv" "$FITS" \
  "$WORK/summ_sumo.csv" "$WORK/summ_trace.csv" "$WORK/summ_scored.csv" "$WORK/summ_ge.csv" "$WORK/summ_bernoulli.csv" \
  "$WORK/per_run_sumo.csv" "$WORK/per_run_trace.csv" "$WORK/per_run_scored.csv" "$WORK/per_run_ge.csv" \
  "$WORK/per_run_bernoulli.csv" > "$TABLE"
cp "$FITS" "$OUT/fits.csv"

# Where the trace is not stationary: per case and mobility realisation (run r replays r mod 4),
# the scored loss, the longest loss run and the mean kalman_extended MSE of those runs (scored
# replay).
SEEDS=$(awk '$1 == "seeds" { print $3 }' "$SC")
{
  echo "receiver,preset,realisation,runs,loss,longest_loss_run,mse_kalman_extended"
  tail -n +2 "$WORK/record/record.csv" | while IFS=, read -r receiver preset _link file _rest; do
    c=${file#v2v_case}; c=${c%.csv}
    awk -F, -v w="$WARMUP" -v p="$PERIODS" -v S="$SEEDS" -v c="$c" -v id="$receiver,$preset" '
      FNR == 1 { ++f }
      f == 1 && FNR == 1 { next }
      f == 1 { r = int($1 / p); k = $1 % p; if (k < w) next; s = r % S; n[s]++
               if (k == w) run = 0
               if ($2 == "") { l[s]++; if (++run > mx[s]) mx[s] = run } else run = 0; next }
      f == 2 && $1 == c && $2 == "kalman_extended" { s = $3 % S; m[s] += $4; cnt[s]++ }
      END { for (s = 0; s < S; ++s) printf "%s,%d,%d,%.4g,%d,%.4g\n", id, s, cnt[s], l[s] / n[s], mx[s], m[s] / cnt[s] }' \
      "$WORK/record/$file" "$WORK/per_run_scored.csv"
  done
} > "$OUT/realisations.csv"

# Heavy tails: per case, estimator and variant, the mean, median and largest per-run MSE and the
# share of the mean that the 3 largest runs carry.
{
  echo "receiver,preset,estimator,variant,mean,median,max,top3_share"
  for v in $VARIANTS; do
    awk -F, -v v="$v" 'FNR == 1 { ++f } f == 1 { if (FNR > 1) rec[FNR - 2] = $1 "," $2; next }
      $2 != "open_loop" { print rec[$1] "," $2 "," v "," $4 }' "$WORK/record/record.csv" "$WORK/per_run_$v.csv"
  done | sort -t, -k1,4 -k5,5g -s | awk -F, '
    function flush() { if (n == 0) return
      med = n % 2 ? a[(n + 1) / 2] : (a[n / 2] + a[n / 2 + 1]) / 2
      printf "%s,%.4g,%.4g,%.4g,%.3f\n", key, s / n, med, a[n], (a[n] + a[n - 1] + a[n - 2]) / s; n = 0; s = 0 }
    { k = $1 "," $2 "," $3 "," $4; if (k != key) { flush(); key = k } a[++n] = $5; s += $5 }
    END { flush() }'
} > "$OUT/tails.csv"

# Markdown: one line per (case, estimator).
awk -F, 'function g(x) { return x == "" ? "–" : sprintf("%.4g", x) }
  function ci(a, b) { return a == "" ? "–" : sprintf("%.4g ± %.2g", a, b) }
  NR == 1 { print "| receiver | preset | estimator | loss | mean loss run | GE bad sojourn | mse sumo | mse trace | mse scored (ref.) | mse GE | mse Bernoulli | trace / ref. | GE / ref. | Bernoulli / ref. |"
            print "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"; next }
  { print "| " $1 " | " $2 " | " $3 " | " g($4) " | " g($5) " | " g($6) " | " ci($12, $13) " | " ci($14, $15) " | " ci($16, $17) " | " ci($18, $19) " | " ci($20, $21) " | " ci($22, $23) " | " ci($24, $25) " | " ci($26, $27) " |" }' \
  "$TABLE" > "$OUT/table.md"

# Figure: per estimator, mse(model) / mse(trace) per case with the paired 95 % CI, log scale.
DAT="$OUT/mse_ratio.dat"
awk -F, 'NR > 1 { n[$3]++; printf "%s %d \"%s %s\" %s %s %s %s %s %s\n", $3, n[$3], $1, $2, $24, $25, $26, $27, $22, $23 }' "$TABLE" |
  sort -s -k1,1 > "$DAT.tmp"
{
  echo "# estimator case label ratio_ge ci95 ratio_bernoulli ci95 ratio_trace ci95 (mse / mse of the scored replay, runs paired)"
  for e in kalman_extended jump; do
    awk -v e="$e" '$1 == e' "$DAT.tmp"
    printf '\n\n'
  done
} > "$DAT"
rm -f "$DAT.tmp"
cat > "$OUT/mse_ratio.gp" <<'GP'
# gnuplot mse_ratio.gp (in results/channel_study/): MSE under each channel model over the MSE
# under the replayed trace (scored periods; warm-up rows delivered), per case, with the paired
# 95 % CI (delta method; a bar whose lower end is <= 0.002 is drawn to the bottom); 1 = the model
# predicts the trace. ego20 cheng2007 (0.02 % delivered: no estimation at all) is off the scale.
if (!exists("fmt")) fmt = "png"
if (fmt eq "svg") { set terminal svg size 1100,560 font "sans,11" noenhanced; set output "mse_ratio.svg" } \
else { set terminal pngcairo size 1100,560 font "sans,10" noenhanced; set output "mse_ratio.png" }
set multiplot layout 1,2 title "SUMO beacons: MSE under a channel model / MSE under the recorded trace replayed (40 runs, paired 95 % CI)"
set logscale y
set yrange [0.002:2000]
set format y "%g"
set xrange [0.5:12.5]
set xtics rotate by 45 right font ",8"
set lmargin 12
set bmargin 8
set grid ytics
set key top left font ",9"
set ylabel "mse(model) / mse(trace replayed, warm-up delivered)"
do for [i = 0:1] {
  set title (i == 0 ? "kalman_extended" : "jump (S3, history 10)")
  plot "mse_ratio.dat" index i using ($2 - 0.15):4:($4 - $5 > 0.002 ? $4 - $5 : 0.002):($4 + $5):xtic(3) with yerrorbars pt 7 ps 0.8 lc rgb "#1f77b4" title "fitted Gilbert-Elliott", \
       "" index i using ($2 + 0.15):6:($6 - $7 > 0.002 ? $6 - $7 : 0.002):($6 + $7) with yerrorbars pt 5 ps 0.8 lc rgb "#d62728" title "Bernoulli, same loss", \
       "" index i using 2:8:($8 - $9 > 0.002 ? $8 - $9 : 0.002):($8 + $9) with yerrorbars pt 9 ps 0.8 lc rgb "#7f7f7f" title "trace with its recorded warm-up", \
       1 with lines lc rgb "black" dt 2 notitle
}
unset multiplot
GP
(cd "$OUT" && gnuplot mse_ratio.gp && gnuplot -e 'fmt="svg"' mse_ratio.gp)
echo "written: $OUT/table.csv, table.md, fits.csv, realisations.csv, tails.csv, mse_ratio.{dat,gp,png,svg}, summary_{sumo,trace,scored,ge,bernoulli}.csv" >&2
