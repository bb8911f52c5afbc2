#!/usr/bin/env bash
# Regenerates every figure of Dolz, Peñarrocha & Sanchis (2014) and Table 2 (results/README.md,
# "Dolz et al. 2014: every figure"): designs (ncosim design -> design.csv), simulations (ncosim run
# with physical packets and the design model: independent copies where the link allows it, fresh
# noise on re-sent buffered samples for Figs. 4-5), the Fig. 5 thresholds (ncosim find), then the gnuplot figures (PNG and SVG).
# Usage, from the repository root after a build: bash scripts/dolz2014_figures.sh
set -euo pipefail
cd "$(dirname "$0")/.."
NCOSIM=${NCOSIM:-build/sim/ncosim}
start=$(date +%s)
run() { echo "+ $*" >&2; "$@" > /dev/null; }
# The design methods of a design.csv whose first column is the swept estimator[0].design.
methods() { awk -F, 'NR > 1 { print $1 }' "$1" | sort -u; }

# Fig. 1 (a)-(c): systems A1, A2, A3.
for s in a b c; do
  out=results/dolz2014_fig1/$s
  run "$NCOSIM" design scenarios/dolz2014_fig1$s.toml --out "$out"
  run "$NCOSIM" run scenarios/dolz2014_fig1$s.toml --out "$out/physical" --quiet --replace
  run "$NCOSIM" run scenarios/dolz2014_fig1$s.toml --out "$out/independent" --quiet --replace \
    --set 'link[0].independent=true' --set 'link[1].independent=true'
  # plot data, one file per design method (column 1): per grouping, gains, predicted ratio,
  # simulated ratios and CIs (extended state).
  rm -f "$out"/plot_*.dat "$out"/plant_block_*.dat
  for m in $(methods "$out/design.csv"); do
  awk -F, -v M="$m" -v D="$out/design.csv" -v P="$out/physical/summary.csv" -v I="$out/independent/summary.csv" '
    BEGIN {
      while ((getline l < D) > 0) { split(l, f, ","); if (f[4] == "reference") ref = f[8];
        else if (f[4] == "jump" && f[1] == M) { k = f[2] " " f[3]; g[k] = f[9]; pr[k] = f[8]; keys[++n] = k } }
      while ((getline l < P) > 0) { split(l, f, ","); if (f[4] == "jump" && f[1] == M) { k = f[2] " " f[3]; ps[k] = f[9]; pc[k] = f[10] } }
      while ((getline l < I) > 0) { split(l, f, ","); if (f[4] == "jump" && f[1] == M) { k = f[2] " " f[3]; is[k] = f[9]; ic[k] = f[10] } }
      print "# grouping history gains predicted/ref physical/ref ci independent/ref ci   (ref = " ref ")"
      for (i = 1; i <= n; i++) { k = keys[i]; split(k, a, " ");
        if (i > 1 && a[1] != prev) print "\n"; prev = a[1];
        printf "%s %s %s %.6g %.6g %.6g %.6g %.6g\n", a[1], a[2], g[k], pr[k] / ref, ps[k] / ref, pc[k] / ref, is[k] / ref, ic[k] / ref }
    }' > "$out/plot_$m.dat"
  # Current-state block (the paper's "1.7 %" of Fig. 1(a) is on it): per grouping, gains, the
  # corrected prediction and the paper's printed eq. (28) (wrong, design.csv column 14), each
  # over its own reference (S4, Nbar = 40).
  awk -F, -v M="$m" '
    $4 == "reference" && $1 == M { ref = $7; ref28 = $14 }
    $4 == "jump" && $1 == M { k = $2 " " $3; g[k] = $9; c[k] = $7; e[k] = $14; keys[++n] = k }
    END {
      print "# grouping history gains corrected/ref printed-eq28/ref   (x[k] block; ref = " ref ", printed-eq28 ref = " ref28 ")"
      for (i = 1; i <= n; i++) { k = keys[i]; split(k, a, " ");
        if (i > 1 && a[1] != prev) print "\n"; prev = a[1];
        printf "%s %s %s %.6g %.6g\n", a[1], a[2], g[k], c[k] / ref, e[k] / ref28 } }' "$out/design.csv" > "$out/plant_block_$m.dat"
  done
done

# Figs. 2-3: A1, sensor 1, negative-binomial delay, dbar = 0..6 (and 9, the reference).
# Beside our corrected prediction: the paper's printed eq. (28) (wrong; design.csv column 13) and
# the FLOPs as the paper counted them for Fig. 3 (nbar_m = 2 whatever dbar, see results/README.md).
out=results/dolz2014_fig3
run "$NCOSIM" design scenarios/dolz2014_fig3.toml --out "$out"
run "$NCOSIM" run scenarios/dolz2014_fig3.toml --out "$out/physical" --quiet --replace
run "$NCOSIM" run scenarios/dolz2014_fig3.toml --out "$out/independent" --quiet --replace --set 'sensor[0].link="net1_independent"'
rm -f "$out"/plot_*.dat
for m in $(methods "$out/design.csv"); do
awk -F, -v M="$m" -v D="$out/design.csv" -v P="$out/physical/summary.csv" -v I="$out/independent/summary.csv" '
  BEGIN {
    while ((getline l < D) > 0) { split(l, f, ","); if (f[3] != "jump" || f[1] != M) continue; if (f[2] == 9) { ref = f[6]; ref28 = f[13]; continue }
      k = f[2]; pr[k] = f[6]; fl[k] = f[9]; p0[k] = f[10]; e28[k] = f[13]; keys[++n] = k }
    while ((getline l < P) > 0) { split(l, f, ","); if (f[3] == "jump" && f[1] == M) { ps[f[2]] = f[6]; pc[f[2]] = f[7] } }
    while ((getline l < I) > 0) { split(l, f, ","); if (f[3] == "jump" && f[1] == M) { is[f[2]] = f[6]; ic[f[2]] = f[7] } }
    print "# dbar predicted/ref flops p0 physical/ref ci independent/ref ci printed-eq28/ref28 flops-as-paper(nbar_m=2)"
    print "#   (plant block; ref = dbar 9: " ref "; printed-eq28 ref28 = dbar 9: " ref28 ")"
    for (i = 1; i <= n; i++) { k = keys[i]; nb = 2 * (k + 1)
      printf "%s %.6g %s %s %.6g %.6g %.6g %.6g %.6g %d\n", k, pr[k] / ref, fl[k], p0[k], ps[k] / ref, pc[k] / ref, is[k] / ref, ic[k] / ref,
        e28[k] / ref28, nb * nb + nb * 1 + 2 * nb * 2 + 2 * nb + 2 }
  }' > "$out/plot_$m.dat"
done

# Fig. 4: A3, buffered packets, dbar = b = 0..3, Nbar = 1..7.
out=results/dolz2014_fig4
run "$NCOSIM" design scenarios/dolz2014_fig4.toml --out "$out"
run "$NCOSIM" run scenarios/dolz2014_fig4.toml --out "$out/physical" --quiet --replace
run "$NCOSIM" run scenarios/dolz2014_fig4.toml --out "$out/fresh" --quiet --replace \
  --set 'sensor[0].resend_noise="fresh"' --set 'sensor[1].resend_noise="fresh"'
rm -f "$out"/plot_*.dat
for m in $(methods "$out/design.csv"); do
awk -F, -v M="$m" -v D="$out/design.csv" -v P="$out/physical/summary.csv" -v F="$out/fresh/summary.csv" '
  BEGIN {
    while ((getline l < D) > 0) { split(l, f, ","); if (f[4] == "jump" && f[1] == M) { k = f[2] " " f[3]; pr[k] = f[7]; pe[k] = f[8]; keys[++n] = k } }
    while ((getline l < P) > 0) { split(l, f, ","); if (f[4] == "jump" && f[1] == M) { k = f[2] " " f[3]; ps[k] = f[7]; pc[k] = f[8]; es[k] = f[9]; ec[k] = f[10] } }
    while ((getline l < F) > 0) { split(l, f, ","); if (f[4] == "jump" && f[1] == M) { k = f[2] " " f[3]; fs[k] = f[7]; fc[k] = f[8] } }
    print "# b Nbar predicted(plant) physical ci predicted(extended) physical ci fresh-resend-noise ci (plant)"
    for (i = 1; i <= n; i++) { k = keys[i]; split(k, a, " ");
      if (i > 1 && a[1] != prev) print "\n"; prev = a[1];
      printf "%s %s %s %s %s %s %s %s %s %s\n", a[1], a[2], pr[k], ps[k], pc[k], pe[k], es[k], ec[k], fs[k], fc[k] }
  }' > "$out/plot_$m.dat"
done

# Fig. 5: A3, sensor 1, buffered packets; tr(Pt) against delivery; thresholds by ncosim find.
out=results/dolz2014_fig5
run "$NCOSIM" design scenarios/dolz2014_fig5.toml --out "$out"
run "$NCOSIM" run scenarios/dolz2014_fig5.toml --out "$out/physical" --quiet --replace
run "$NCOSIM" run scenarios/dolz2014_fig5.toml --out "$out/fresh" --quiet --replace --set 'sensor[0].resend_noise="fresh"'
run "$NCOSIM" find scenarios/dolz2014_fig5.toml --key 'link[0].delivery' --target 'predicted_mse<=0.03' \
  --lo 0.5 --hi 1 --tol 1e-5 --out "$out/find"
awk -F, -v D="$out/design.csv" -v P="$out/physical/summary.csv" -v F="$out/fresh/summary.csv" '
  BEGIN {
    while ((getline l < D) > 0) { split(l, f, ","); if (f[1] ~ /^[0-9.]+$/) { k = f[2] "|" f[1]; pr[k] = f[5]; keys[++n] = k } }
    while ((getline l < P) > 0) { split(l, f, ","); if (f[1] ~ /^[0-9.]+$/) { k = f[2] "|" f[1]; ps[k] = f[5]; pc[k] = f[6] } }
    while ((getline l < F) > 0) { split(l, f, ","); if (f[1] ~ /^[0-9.]+$/) { k = f[2] "|" f[1]; fs[k] = f[5]; fc[k] = f[6] } }
    print "# estimator delivery predicted(plant) physical ci fresh-resend-noise ci"
    for (i = 1; i <= n; i++) { k = keys[i]; split(k, a, "|"); if (!(a[1] in seen)) { seen[a[1]] = 1; names[++m] = a[1] } }
    for (j = 1; j <= m; j++) { if (j > 1) print "\n"; for (i = 1; i <= n; i++) { k = keys[i]; split(k, a, "|");
      if (a[1] == names[j]) printf "\"%s\" %s %s %s %s %s %s\n", a[1], a[2], pr[k], ps[k], pc[k], fs[k], fc[k] } }
  }' > "$out/plot.dat"

# Table 2: physical packets (the committed reference) and the independent copies of the design model.
out=results/dolz2014_table2
run "$NCOSIM" run scenarios/dolz2014_table2.toml --out "$out" --quiet --replace
run "$NCOSIM" run scenarios/dolz2014_table2.toml --out "$out/independent" --quiet --replace \
  --set 'link[0].independent=true' --set 'link[1].independent=true'
# The same campaign with the paper's design method (CCL + bisection on CSDP) for every jump row.
ccl_sets=(); for i in 0 1 2 3 4; do ccl_sets+=(--set "estimator[$i].design=\"ccl\""); done
run "$NCOSIM" run scenarios/dolz2014_table2.toml --out "$out/ccl" --quiet --replace "${ccl_sets[@]}"
awk -F, -v I="$out/independent/summary.csv" -v C="$out/ccl/summary.csv" '
  function field(line, i,   f, n, q, c, s) { # CSV with quoted names: split respecting quotes
    n = 0; s = ""; q = 0
    for (c = 1; c <= length(line); c++) { ch = substr(line, c, 1)
      if (ch == "\"") { q = !q; continue }
      if (ch == "," && !q) { F[++n] = s; s = ""; continue }
      s = s ch }
    F[++n] = s; return n }
  BEGIN {
    paper["S1, 1 gain"] = 0.1585; paper["S2, 2 gains"] = 0.0781; paper["S3, 4 gains"] = 0.0553
    paper["S3, 8 gains"] = 0.0498; paper["S4, 60 gains"] = 0.0451; paper["Kalman"] = 0.0423
    while ((getline l < I) > 0) { field(l); ind[F[1]] = sprintf("%.4f ± %.4f", F[6], F[7]) }
    while ((getline l < C) > 0) { field(l); csim[F[1]] = sprintf("%.4f ± %.4f", F[6], F[7]); cpred[F[1]] = F[14] }
    print "| case | gains | paper tr(Pt) | predicted, iterative | predicted, CCL | lower prediction | simulated, physical packets (iterative) | simulated, physical packets (CCL) | simulated, independent copies (iterative) | FLOPs |"
    print "|---|---|---|---|---|---|---|---|---|---|"
  }
  NR > 1 { field($0); if (!(F[1] in paper)) next
    it = F[14]; cc = cpred[F[1]]; lower = "–"
    if (it != "" && cc != "") lower = (it + 0 < (cc + 0) * (1 - 1e-6)) ? "iterative" : ((cc + 0 < (it + 0) * (1 - 1e-6)) ? "CCL" : "equal (1e-6)")
    printf "| %s | %s | %.4f | %s | %s | %s | %.4f ± %.4f | %s | %s | %s |\n", F[1], (F[12] == "" ? "–" : F[12]), paper[F[1]],
      (it == "" ? "–" : sprintf("%.6f", it)), (cc == "" ? "–" : sprintf("%.6f", cc)), lower, F[6], F[7],
      (F[1] in csim && cc != "" ? csim[F[1]] : "–"), ind[F[1]], F[11] }' "$out/summary.csv" > "$out/table2.md"

for d in dolz2014_fig1 dolz2014_fig3 dolz2014_fig4 dolz2014_fig5; do
  (cd "results/$d" && gnuplot plot.gp)
done
echo "all figures regenerated in $(( $(date +%s) - start )) s" >&2
