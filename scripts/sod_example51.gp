# Figures of example 5.1 (send-on-delta co-design paper) from sweep.csv: gnuplot -e "dir='...'"
set datafile separator ","
set terminal svg size 900,600 dynamic enhanced font "sans,12"
set key outside right
set grid
cases = "C1 C2 C3 C4 C3_lower"
sel(c) = sprintf("< awk -F, 'NR == 1 || $1 == \"%s\"' %s/sweep.csv", c, dir)

set output dir."/fig1_thresholds.svg"
set title "Fig. 1: co-designed thresholds against mu"
set xlabel "mu"; set ylabel "Delta_i"
plot for [c in cases] sel(c) using 2:9 with linespoints title c." Delta_1", \
     for [c in cases] sel(c) using 2:10 with linespoints dashtype 2 title c." Delta_2"

set output dir."/fig2_beta_virtual_noise.svg"
set multiplot layout 1,2 title "Fig. 2: send probability and virtual-noise RMS against Delta (r = [0.9 0.75])"
set title "beta_i"; set xlabel "Delta_i"; set ylabel "beta"
r1 = 0.9; r2 = 0.75
ub(d, r) = d < r ? (r - d)**2 / r**2 : 0
us(d, r) = d < r ? sqrt(2 * d**3 / r**2 * (r / 3 - d / 4)) : r / sqrt(6)
set xrange [0:0.6]
plot dir."/sweep.csv" using 9:19 with points pt 7 title "simulation, sensor 1", \
     dir."/sweep.csv" using 10:20 with points pt 5 title "simulation, sensor 2", \
     ub(x, r1) title "uniform (29), r_1", ub(x, r2) dashtype 2 title "uniform (29), r_2"
set title "virtual-noise RMS"; set ylabel "RMS of m - y"
plot dir."/sweep.csv" using 9:21 with points pt 7 title "simulation, sensor 1", \
     dir."/sweep.csv" using 10:22 with points pt 5 title "simulation, sensor 2", \
     us(x, r1) title "uniform (30), r_1", us(x, r2) dashtype 2 title "uniform (30), r_2", \
     x / sqrt(3) dashtype 3 title "Delta/sqrt(3) (Suh)"
unset multiplot
set xrange [*:*]

set output dir."/fig3_transmissions.svg"
set title "Fig. 3: transmissions per period (both sensors) against mu"
set xlabel "mu"; set ylabel "packets per period"
plot for [c in cases] sel(c) using 2:18 with linespoints title c

set output dir."/fig4_error.svg"
set title "Fig. 4: simulated ||z~||^2_RMS against the prescribed bound mu z~0"
set xlabel "mu"; set ylabel "||z~||^2_RMS"
plot for [c in cases] sel(c) using 2:16 with linespoints title c." simulated", \
     dir."/sweep.csv" using 2:4 with lines lw 2 lc rgb "black" title "mu z~0 (bound)"
