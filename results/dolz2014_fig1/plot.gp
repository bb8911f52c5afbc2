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

# Fig. 1(a), current-state block x[k]: our corrected prediction and the paper's eq. (28) as printed
# (wrong), each over its own reference (S4, Nbar = 40). The paper's "S1 is 1.7 % worse than the
# optimum" is the printed form (results/README.md). Data: a/plant_block_<method>.dat.
files = system("ls a/plant_block_*.dat")
method(f) = system(sprintf("basename %s .dat | sed 's/^plant_block_//'", f))
set title "Fig. 1(a), A_1, current-state block: corrected eq. (28) (lines) and eq. (28) as printed (red, wrong)"
set ylabel "tr(P_t x-block) / tr(P_t^* x-block)"
do for [t in "pngcairo svg"] {
  if (t eq "svg") { set terminal svg size 900,620 dynamic; set output "fig1a_plant_block.svg" } \
  else { set terminal pngcairo size 900,620; set output "fig1a_plant_block.png" }
  plot for [m=1:words(files)] for [g=0:3] word(files, m) index g using 3:4 with linespoints lw 2 pt 7 lc g+1 dt m \
         title sprintf("S%d corrected (%s)", g+1, method(word(files, m))), \
       for [m=1:words(files)] for [g=0:3] word(files, m) index g using 3:5 with linespoints lw 1 pt 6 lc g+1 dt 2 \
         title sprintf("S%d printed eq. (28) (%s)", g+1, method(word(files, m))), \
       1.017 with lines lc rgb "black" dt 3 title "paper: S1 1.7 % above the optimum"
  unset output
}
