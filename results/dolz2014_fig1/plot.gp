# Fig. 1 (a)-(c) of Dolz et al. 2014: tr(Pt)/tr(Pt*) against the number of stored gains.
# Lines: prediction of the design (ncosim design); points: simulation with 95% CI, independent
# copies (the design model, filled) and physical packets (open). Data: <a|b|c>/plot.dat.
set datafile separator whitespace
set key top right
set xlabel "number of stored gains |L|"
set ylabel "tr(P_t) / tr(P_t^*)"
set logscale x
set grid
titles = "A_1 A_2 A_3"
do for [s in "a b c"] {
  i = s eq "a" ? 1 : s eq "b" ? 2 : 3
  set title sprintf("Fig. 1(%s): system %s (extended state; P_t^* = S4, Nbar = 40)", s, word(titles, i))
  f = s."/plot.dat"
  do for [t in "pngcairo svg"] {
    if (t eq "svg") { set terminal svg size 800,560 dynamic; set output "fig1".s.".svg" } \
    else { set terminal pngcairo size 800,560; set output "fig1".s.".png" }
    plot for [g=0:3] f index g using 3:4 with linespoints lw 2 pt 7 lc g+1 title sprintf("S%d predicted", g+1), \
         for [g=0:3] f index g using 3:7:8 with yerrorbars pt 5 lc g+1 title sprintf("S%d simulated, independent copies", g+1), \
         for [g=0:3] f index g using 3:5:6 with yerrorbars pt 4 lc g+1 dt 2 title sprintf("S%d simulated, physical", g+1)
    unset output
  }
}
