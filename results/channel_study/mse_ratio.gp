# gnuplot mse_ratio.gp (in results/channel_study/): MSE under each channel model over the MSE
# under the replayed trace (scored periods; warm-up rows delivered), per case, with the paired
# 95 % CI (delta method; a bar whose lower end is <= 0.002 is drawn to the bottom); 1 = the model
# predicts the trace. ego20 cheng2007 (0.02 % delivered: no estimation at all) is off the scale.
if (!exists("fmt")) fmt = "png"
if (fmt eq "svg") { set terminal svg size 1100,560 font "sans,11" noenhanced; set output "mse_ratio.svg" } \
else { set terminal pngcairo size 1100,560 font "sans,10" noenhanced; set output "mse_ratio.png" }
set multiplot layout 1,2 title "SUMO beacons: MSE under a channel model / MSE under the recorded trace replayed (40 runs, paired 95 % CI)"
set logscale y
set yrange [0.002:2000]
set format y "%g"
set xrange [0.5:12.5]
set xtics rotate by 45 right font ",8"
set lmargin 12
set bmargin 8
set grid ytics
set key top left font ",9"
set ylabel "mse(model) / mse(trace replayed, warm-up delivered)"
do for [i = 0:1] {
  set title (i == 0 ? "kalman_extended" : "jump (S3, history 10)")
  plot "mse_ratio.dat" index i using ($2 - 0.15):4:($4 - $5 > 0.002 ? $4 - $5 : 0.002):($4 + $5):xtic(3) with yerrorbars pt 7 ps 0.8 lc rgb "#1f77b4" title "fitted Gilbert-Elliott", \
       "" index i using ($2 + 0.15):6:($6 - $7 > 0.002 ? $6 - $7 : 0.002):($6 + $7) with yerrorbars pt 5 ps 0.8 lc rgb "#d62728" title "Bernoulli, same loss", \
       "" index i using 2:8:($8 - $9 > 0.002 ? $8 - $9 : 0.002):($8 + $9) with yerrorbars pt 9 ps 0.8 lc rgb "#7f7f7f" title "trace with its recorded warm-up", \
       1 with lines lc rgb "black" dt 2 notitle
}
unset multiplot
