# Figs. 2-3 of Dolz et al. 2014 (example 2). Fig. 2: the negative-binomial delay pmf
# P[d] = C(d+2, 2) 0.5^(d+3). Fig. 3: normalised tr(Pt) (plant block, against dbar = 9), FLOPs
# and p0 against dbar; points: simulation with 95% CI. Red: the paper's eq. (28) as printed (wrong)
# and its FLOP count with nbar_m = 2, which together reproduce the printed Fig. 3 (results/README.md). Data: plot_<method>.dat, one per design
# method (scripts/dolz2014_figures.sh).
set datafile separator whitespace
set grid
do for [t in "pngcairo svg"] {
  if (t eq "svg") { set terminal svg size 700,420 dynamic; set output "fig2.svg" } \
  else { set terminal pngcairo size 700,420; set output "fig2.png" }
  set title "Fig. 2: delay distribution (negative binomial, p = 0.5, 3 failures)"
  set xlabel "delay d (periods)"; set ylabel "P[d]"
  set xrange [-0.5:19.5]; set samples 20
  plot '+' using (int($1)):(gamma(int($1)+3)/(2*gamma(int($1)+1))*0.5**(int($1)+3)) with impulses lw 4 notitle
  unset output
  set autoscale x
  unset title
}
set samples 100
files = system("ls plot_*.dat")
# The paper's text (section 6.2): dbar = 4, 3, 2 are 7, 20, 51 % above its dbar -> inf.
$paper << EOD
2 1.51
3 1.20
4 1.07
EOD
method(f) = system(sprintf("basename %s .dat | sed 's/^plot_//'", f))
do for [t in "pngcairo svg"] {
  if (t eq "svg") { set terminal svg size 760,1000 dynamic; set output "fig3.svg" } \
  else { set terminal pngcairo size 760,1000; set output "fig3.png" }
  set multiplot layout 3,1 title "Fig. 3: A_1, sensor 1, S4 (Nbar = 1)"
  set xlabel "dbar"; set xrange [-0.5:6.5]
  set ylabel "tr(P_t) / tr(P_t, dbar = 9)  (log)"; set key top right font ",8"; set logscale y
  plot for [m=1:words(files)] word(files, m) using 1:2 with linespoints lw 2 pt 7 dt m title "predicted, corrected eq. (28) (".method(word(files, m)).")", \
       for [m=1:words(files)] word(files, m) using 1:9 with linespoints lw 2 pt 6 lc rgb "#d62728" dt m title "paper's eq. (28) as printed (wrong; ".method(word(files, m)).")", \
       $paper using 1:2 with points pt 9 ps 1.6 lc rgb "black" title "paper's text: 51 / 20 / 7 % above dbar -> inf", \
       for [m=1:words(files)] word(files, m) using ($1+0.08):7:8 with yerrorbars pt 5 title "simulated, independent copies (".method(word(files, m)).")", \
       for [m=1:words(files)] word(files, m) using ($1-0.08):5:6 with yerrorbars pt 4 title "simulated, physical (".method(word(files, m)).")"
  unset logscale y; set ylabel "FLOPs per period"; set key top left
  plot word(files, 1) using 1:3 with linespoints lw 2 pt 7 title "section 2 formula, nbar_m = n_m (dbar + 1)", \
       word(files, 1) using 1:10 with linespoints lw 2 pt 6 lc rgb "#d62728" title "as the paper counted: nbar_m = 2"
  set ylabel "p_0"; plot word(files, 1) using 1:4 with linespoints lw 2 pt 7 notitle
  unset multiplot
  unset output
}
