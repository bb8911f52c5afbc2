# results/sumo_beacons/figure.gp — MSE of the leader's (position, speed) estimate against the
# beacons' delivery ratio, one point per (receiver, channel preset) case of summary.csv.
# Run from this folder: gnuplot figure.gp  (writes figure.png and figure.svg)
set datafile separator ','
set key top right box opaque
set logscale y
set format y '10^{%L}'
set xlabel 'delivery ratio of the beacons (after warm-up)'
set ylabel 'MSE of (position, speed)  [m^2 + (m/s)^2]'
set title "Leader tracking over sumo\\_distance (SUMO motorway, 40 runs/case)\nopen loop (no beacons): MSE 1.35e7 in every case"
set grid
set xrange [-0.02:1.02]
f(kind) = (strcol(3) eq kind) ? $6 : 1/0
plot_cmd = "plot 'summary.csv' skip 1 using 17:(f('kalman_extended')) with points pt 7 ps 1.3 title 'kalman\\_extended', \
  '' skip 1 using 17:(f('jump')) with points pt 5 ps 1.1 title 'jump (S3, N = 10)'"
set terminal pngcairo size 900,560 enhanced font 'Sans,11'
set output 'figure.png'
eval plot_cmd
set terminal svg size 900,560 enhanced font 'Sans,11'
set output 'figure.svg'
eval plot_cmd
