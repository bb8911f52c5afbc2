# Fig. 1 (a)-(c) of Dolz et al. 2014: tr(Pt)/tr(Pt*) against the number of stored gains.
# Lines: prediction of the design (ncosim design), one dash type per design method; points:
# simulation with 95% CI, independent copies (the design model, filled) and physical packets
# (open). Data: <a|b|c>/plot_<method>.dat (one per design method, scripts/dolz2014_figures.sh).
set datafile separator whitespace
set key top right
set xlabel "number of stored gains |L|"
set ylabel "tr(P_t) / tr(P_t^*)"
set logscale x
set grid
titles = "A_1 A_2 A_3"
method(f) = system(sprintf("basename %s .dat | sed 's/^plot_//'", f))
do for [s in "a b c"] {
  i = s eq "a" ? 1 : s eq "b" ? 2 : 3
  files = system("ls ".s."/plot_*.dat")
  set title sprintf("Fig. 1(%s): system %s (extended state; P_t^* = S4, Nbar = 40)", s, word(titles, i))
  do for [t in "pngcairo svg"] {
    if (t eq "svg") { set terminal svg size 900,620 dynamic; set output "fig1".s.".svg" } \
    else { set terminal pngcairo size 900,620; set output "fig1".s.".png" }
    plot for [m=1:words(files)] for [g=0:3] word(files, m) index g using 3:4 with linespoints lw 2 pt 7 lc g+1 dt m \
           title sprintf("S%d predicted (%s)", g+1, method(word(files, m))), \
         for [m=1:words(files)] for [g=0:3] word(files, m) index g using 3:7:8 with yerrorbars pt 5 lc g+1 \
           title sprintf("S%d simulated, independent copies (%s)", g+1, method(word(files, m))), \
         for [m=1:words(files)] for [g=0:3] word(files, m) index g using 3:5:6 with yerrorbars pt 4 lc g+1 \
           title sprintf("S%d simulated, physical (%s)", g+1, method(word(files, m)))
    unset output
  }
}
