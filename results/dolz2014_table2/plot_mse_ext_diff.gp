# plot_mse_ext_diff.gp — paired mse_ext: mse_ext − mse_ext of the reference (Kalman) on the same runs, 95 % CI, 20 runs — Dolz et al. 2014, example 1, system A3 (Table 2), written by `ncosim plot`.
# Run in this folder: gnuplot plot_mse_ext_diff.gp   (one format: gnuplot -e "formats='svg'" plot_mse_ext_diff.gp)
set encoding utf8
if (!exists("formats")) formats = 'png svg'
set datafile missing '?'
do for [fmt in formats] {
  if (fmt eq 'png') { set terminal pngcairo size 1020,560 noenhanced font 'Sans,10'; set output 'plot_mse_ext_diff.png' }
  if (fmt eq 'svg') { set terminal svg size 1020,560 noenhanced font 'Sans,10' background '#ffffff'; set output 'plot_mse_ext_diff.svg' }
  reset
  set datafile missing '?'
  set title 'paired mse_ext: mse_ext − mse_ext of the reference (Kalman) on the same runs, 95 % CI, 20 runs — Dolz et al. 2014, example 1, system A3 (Table 2)'
  set ylabel 'mse_ext_diff  (bars: 95 % CI)'
  set grid
  set xzeroaxis lt -1 lw 1.5
  set xtics rotate by -25 ('S1, 1 gain' 0, 'S2, 2 gains' 1, 'S3, 4 gains' 2, 'S3, 8 gains' 3, 'S4, 60 gains' 4, 'Kalman (reference)' 5, 'open loop (no mse_ext_diff)' 6)
  set xrange [-0.6:6.6]
  set bmargin 9
  set key outside bottom center horizontal
  plot 'plot_mse_ext_diff.dat' using 1:2:($2-$3):($2+$3) with yerrorbars pt 7 ps 1.2 lc rgb '#1f77b4' title 'simulated, 95 % CI'
  unset multiplot
  set output
}
