# Fig. 6 of the send-on-delta co-design paper (example 5.2) from the two traced runs.
set datafile separator ","
set terminal svg size 1100,700 dynamic enhanced font "sans,11"
set output dir."/fig6.svg"
set multiplot layout 2,2 title "Example 5.2: PI on received measurements (left) vs inferential PI (right), t in [2, 4] s"
set grid
set xrange [2:4]
T = 0.005
set xlabel "t (s)"; set ylabel "speed (rad/s)"
set title "PI on the last received measurement"
f = dir."/trajectory_received.csv"
plot f using ($1*T):(column("reference")) with lines lc rgb "gray" title "reference", \
     f using ($1*T):(column("y:speed")) with lines lc rgb "blue" title "speed", \
     f using ($1*T):(column("arrived:speed") > 0 ? column("y:speed") : 1/0) with points pt 6 lc rgb "red" title "sent"
set title "inferential PI (observer output)"
g = dir."/trajectory_sod_jump.csv"
plot g using ($1*T):(column("reference")) with lines lc rgb "gray" title "reference", \
     g using ($1*T):(column("y:speed")) with lines lc rgb "blue" title "speed", \
     g using ($1*T):(column("sod_jump:xhat1")) with lines lw 2 lc rgb "black" title "estimate C x^", \
     g using ($1*T):(column("arrived:speed") > 0 ? column("y:speed") : 1/0) with points pt 6 lc rgb "red" title "sent"
set ylabel "u (V)"
set title "control action"
plot f using ($1*T):(column("u1")) with steps lc rgb "blue" title "u"
plot g using ($1*T):(column("u1")) with steps lc rgb "blue" title "u"
unset multiplot
