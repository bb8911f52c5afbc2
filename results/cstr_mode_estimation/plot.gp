# results/cstr_mode_estimation/plot.gp — run 0 of the CSTR reproduction: true vs estimated mode
# (1-4 in the paper's Table 1 numbering) and the two states. From the repository root:
#   gnuplot results/cstr_mode_estimation/plot.gp
# Reads trajectory.csv (ncosim run ... --trace); writes trial0.png and trial0.svg beside it.
dir = 'results/cstr_mode_estimation/'
set datafile separator ','
set key outside right top
set xlabel 'step k'
do for [t in 'png svg'] {
  if (t eq 'png') { set terminal png size 1100,1000; set output dir.'trial0.png' } \
  else { set terminal svg size 1100,1000 dynamic; set output dir.'trial0.svg' }
  set multiplot layout 3,1 title 'Moayedi et al. CSTR example, run 0: true vs estimated (mode of step k-1 estimated at k)'
  set ylabel 'mode theta(k-1)'
  set yrange [0.5:4.5]
  set ytics 1
  plot dir.'trajectory.csv' every ::2 using 1:($11+1) with steps lw 3 lc rgb 'black' title 'true', \
       '' every ::2 using 1:($12+1.08) with points pt 7 ps 0.6 lc rgb '#1f77b4' title 'Algorithm 1', \
       '' every ::2 using 1:($13+0.92) with points pt 5 ps 0.6 lc rgb '#d62728' title 'Algorithm 2', \
       '' every ::2 using 1:($14+1) with points pt 6 ps 1.0 lc rgb '#2ca02c' title 'IMM'
  set autoscale y
  set ytics autofreq
  set ylabel 'x1'
  plot dir.'trajectory.csv' every ::1 using 1:2 with lines lw 2 lc rgb 'black' title 'true', \
       '' every ::1 using 1:4 with lines lc rgb '#1f77b4' title 'Algorithm 1', \
       '' every ::1 using 1:6 with lines lc rgb '#d62728' title 'Algorithm 2', \
       '' every ::1 using 1:8 with lines dt 2 lc rgb '#2ca02c' title 'IMM'
  set ylabel 'x2'
  plot dir.'trajectory.csv' every ::1 using 1:3 with lines lw 2 lc rgb 'black' title 'true', \
       '' every ::1 using 1:5 with lines lc rgb '#1f77b4' title 'Algorithm 1', \
       '' every ::1 using 1:7 with lines lc rgb '#d62728' title 'Algorithm 2', \
       '' every ::1 using 1:9 with lines dt 2 lc rgb '#2ca02c' title 'IMM'
  unset multiplot
}
