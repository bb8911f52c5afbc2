# Fig. 5 of Dolz et al. 2014: tr(Pt) (plant block) against the delivery probability beta1 of
# sensor 1 (A3, buffered packets, S4), Nbar = 1, 4 and b = 0, 3. Lines: prediction; points:
# simulation with 95% CI of physical packets (open) and with resend_noise = "fresh" (filled, the
# design model); the dashed line is the target 0.03 and the crosses
# are the thresholds found by `ncosim find` (find/find.csv). Data: plot.dat.
set datafile separator whitespace
set grid
set xlabel "beta_1 (delivery probability of sensor 1)"; set ylabel "tr(P_t), plant block"
set key top right
set yrange [0:0.1]
do for [t in "pngcairo svg"] {
  if (t eq "svg") { set terminal svg size 800,560 dynamic; set output "fig5.svg" } \
  else { set terminal pngcairo size 800,560; set output "fig5.png" }
  set title "Fig. 5: minimum beta_1 with tr(P_t) <= 0.03 (paper: 0.9730 Nbar=1 b=0, 0.8530 Nbar=4 b=3)"
  plot for [e=0:3] "plot.dat" index e using 2:3 with lines lw 2 lc e+1 title word("Nbar=1,b=0 Nbar=4,b=0 Nbar=1,b=3 Nbar=4,b=3", e+1)." predicted", \
       for [e=0:3] "plot.dat" index e using 2:4:5 with yerrorbars pt 4 lc e+1 notitle, \
       for [e=0:3] "plot.dat" index e using ($2+0.002):6:7 with yerrorbars pt 5 lc e+1 notitle, \
       0.03 with lines dt 2 lc "black" title "target 0.03", \
       "< awk -F, 'NR > 1 {print $6, $8}' find/find.csv" using 1:2 with points pt 2 ps 2 lw 2 lc "black" title "ncosim find"
  unset output
}
