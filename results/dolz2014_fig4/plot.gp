# Fig. 4 of Dolz et al. 2014 (example 3): tr(Pt) (plant block) against Nbar for every buffer
# length b (S4, dbar = b). Lines: prediction of the design model; points: simulation with 95% CI,
# of physical buffered packets (open) and with resend_noise = "fresh" (filled: the design model
# counts a re-sent sample as a new measurement, results/README.md). Data: plot_<method>.dat, one per design method.
set datafile separator whitespace
set grid
set xlabel "Nbar"; set ylabel "tr(P_t), plant block"
set key top right
files = system("ls plot_*.dat")
method(f) = system(sprintf("basename %s .dat | sed 's/^plot_//'", f))
do for [t in "pngcairo svg"] {
  if (t eq "svg") { set terminal svg size 800,560 dynamic; set output "fig4.svg" } \
  else { set terminal pngcairo size 800,560; set output "fig4.png" }
  set title "Fig. 4: A_3, buffered packets, beta = (0.66, 0.11), S4, dbar = b"
  plot for [m=1:words(files)] for [b=0:3] word(files, m) index b using 2:3 with linespoints lw 2 pt 7 lc b+1 dt m \
         title sprintf("b = %d predicted (%s)", b, method(word(files, m))), \
       for [m=1:words(files)] for [b=0:3] word(files, m) index b using ($2+0.05):4:5 with yerrorbars pt 4 lc b+1 \
         title sprintf("b = %d simulated, physical (%s)", b, method(word(files, m))), \
       for [m=1:words(files)] for [b=0:3] word(files, m) index b using ($2-0.05):9:10 with yerrorbars pt 5 lc b+1 \
         title sprintf("b = %d simulated, fresh resend noise (%s)", b, method(word(files, m)))
  unset output
}
