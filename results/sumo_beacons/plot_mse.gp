# plot_mse.gp — mse with 95 % CI, 40 runs — Leader tracking from 10 Hz V2V beacons in motorway traffic (SUMO), written by `ncosim plot`.
# Run in this folder: gnuplot plot_mse.gp   (one format: gnuplot -e "formats='svg'" plot_mse.gp)
set encoding utf8
if (!exists("formats")) formats = 'png svg'
set datafile missing '?'
do for [fmt in formats] {
  if (fmt eq 'png') { set terminal pngcairo size 1040,860 noenhanced font 'Sans,10'; set output 'plot_mse.png' }
  if (fmt eq 'svg') { set terminal svg size 1040,860 noenhanced font 'Sans,10' background '#ffffff'; set output 'plot_mse.svg' }
  reset
  set datafile missing '?'
  set title 'mse with 95 % CI, 40 runs — Leader tracking from 10 Hz V2V beacons in motorway traffic (SUMO)'
  set ylabel 'mse  (bars: 95 % CI)'
  set grid
  set logscale y
  set xlabel 'link[0].receiver'
  set xtics ('ego2' 0, 'ego5' 1, 'ego10' 2, 'ego20' 3)
  set xrange [-0.5:3.5]
  set yrange [0.0122488:2.7136e+08]
  set multiplot layout 2,2 title 'mse with 95 % CI, 40 runs — Leader tracking from 10 Hz V2V beacons in motorway traffic (SUMO)'
  set key top left font ',8' box opaque
  set title 'link[0].preset = veins_nakagami3'
  plot 'plot_mse.dat' index 0 using ($1-0.060):2:($2-$3 > 0 ? $2-$3 : $2*1e-3):($2+$3) with yerrorlines lc rgb '#1f77b4' pt 1 ps 1.0 title 'kalman_extended', \
       'plot_mse.dat' index 1 using ($1+0.000):2:($2-$3 > 0 ? $2-$3 : $2*1e-3):($2+$3) with yerrorlines lc rgb '#d62728' pt 2 ps 1.0 title 'jump', \
       '' index 1 using ($1+0.000):4 with lines dt 2 lc rgb '#d62728' title 'jump, predicted', \
       'plot_mse.dat' index 2 using ($1+0.060):2:($2-$3 > 0 ? $2-$3 : $2*1e-3):($2+$3) with yerrorlines lc rgb '#2ca02c' pt 3 ps 1.0 title 'open_loop'
  set title 'link[0].preset = ns3_vanet'
  unset key
  plot 'plot_mse.dat' index 3 using ($1-0.060):2:($2-$3 > 0 ? $2-$3 : $2*1e-3):($2+$3) with yerrorlines lc rgb '#1f77b4' pt 1 ps 1.0 title 'kalman_extended', \
       'plot_mse.dat' index 4 using ($1+0.000):2:($2-$3 > 0 ? $2-$3 : $2*1e-3):($2+$3) with yerrorlines lc rgb '#d62728' pt 2 ps 1.0 title 'jump', \
       '' index 4 using ($1+0.000):4 with lines dt 2 lc rgb '#d62728' title 'jump, predicted', \
       'plot_mse.dat' index 5 using ($1+0.060):2:($2-$3 > 0 ? $2-$3 : $2*1e-3):($2+$3) with yerrorlines lc rgb '#2ca02c' pt 3 ps 1.0 title 'open_loop'
  set title 'link[0].preset = cheng2007'
  plot 'plot_mse.dat' index 6 using ($1-0.060):2:($2-$3 > 0 ? $2-$3 : $2*1e-3):($2+$3) with yerrorlines lc rgb '#1f77b4' pt 1 ps 1.0 title 'kalman_extended', \
       'plot_mse.dat' index 7 using ($1+0.000):2:($2-$3 > 0 ? $2-$3 : $2*1e-3):($2+$3) with yerrorlines lc rgb '#d62728' pt 2 ps 1.0 title 'jump', \
       '' index 7 using ($1+0.000):4 with lines dt 2 lc rgb '#d62728' title 'jump, predicted', \
       'plot_mse.dat' index 8 using ($1+0.060):2:($2-$3 > 0 ? $2-$3 : $2*1e-3):($2+$3) with yerrorlines lc rgb '#2ca02c' pt 3 ps 1.0 title 'open_loop'
  unset multiplot
  set output
}
