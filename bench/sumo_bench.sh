#!/bin/sh
# bench/sumo_bench.sh — SUMO co-simulation timings (bench/README.md): on the 4x4 grid with 100
# and 1000 vehicles, 3000 steps of 0.1 s:
#   bare      the `sumo` binary alone (exactly the options ncosim's recording passes, without
#             the FCD output)
#   fcd       the same `sumo` command with the recording's FCD options (SUMO's own share)
#   record    `ncosim check` with an empty cache: ncosim start-up, input hashing, the `sumo`
#             process with FCD output for the 2 named vehicles, FCD parsing, the .traj file
#   replay    `ncosim run --runs 100` with the recording cached, per run
#   live      `ncosim run --runs 4` with sumo.mode = "live" (one `ncosim sumo-live` worker
#             process per run, libsumo stepped there), per run
#   startup   `ncosim list` and `sumo --version`
# bare, fcd and record also report CPU seconds (user + system of the process and its children),
# which the other processes of a loaded machine disturb less than wall-clock time.
# bare, fcd and record are measured alternately, ROUNDS (default 7) times; the figure is the median of
# the per-round ratios record/bare (robust to the load of other processes on the machine), with
# the medians of each. replay and live: median of REPEAT (default 3). The load average is printed
# before and after.
# Usage: bench/sumo_bench.sh [BUILD_DIR]   (after scenarios/sumo/make_inputs.sh)
set -eu
here=$(cd "$(dirname "$0")" && pwd)
build=${1:-$here/../build}
ncosim="$build/sim/ncosim"
repeat=${REPEAT:-3}
rounds=${ROUNDS:-7}
export SUMO_HOME=${SUMO_HOME:-/usr/share/sumo}
gen="$here/../scenarios/sumo/gen"
[ -f "$gen/grid.net.xml" ] || { echo "run scenarios/sumo/make_inputs.sh first" >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# wall seconds of a command (stdout and stderr discarded)
wall() { cost "$@" | cut -d' ' -f1; }
# "wall cpu": wall seconds and CPU seconds (user + system, the command and its children)
cost() {
  python3 - "$@" <<'PY'
import resource, subprocess, sys, time
r0, t = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
w, r1 = time.perf_counter() - t, resource.getrusage(resource.RUSAGE_CHILDREN)
print(f"{w:.4f} {r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime:.4f}")
PY
}
median() { sort -n | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }

echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'); load: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "startup  ncosim list:    $(for i in $(seq $repeat); do wall "$ncosim" list; done | median) s"
echo "startup  sumo --version: $(for i in $(seq $repeat); do wall sumo --version; done | median) s"
for n in 100 1000; do
  routes="../scenarios/sumo/gen/grid$n.rou.xml"
  : >"$tmp/rounds"
  for i in $(seq $rounds); do
    bare=$(cost sumo -n "$gen/grid.net.xml" -r "$gen/grid$n.rou.xml" --no-step-log true --no-warnings true \
      --duration-log.disable true --xml-validation never --xml-validation.net never --xml-validation.routes never \
      --seed 1 --step-length 0.1 --begin 0 --end 299.9)
    fcd=$(cost sumo -n "$gen/grid.net.xml" -r "$gen/grid$n.rou.xml" --no-step-log true --no-warnings true \
      --duration-log.disable true --xml-validation never --xml-validation.net never --xml-validation.routes never \
      --seed 1 --step-length 0.1 --begin 0 --end 299.9 --fcd-output "$tmp/fcd.xml" --device.fcd.explicit 0,1 \
      --fcd-output.attributes x,y,speed,acceleration,odometer --precision 40)
    rm -rf "$tmp/cache"
    record=$(cost "$ncosim" check "$here/sumo_grid.toml" --set "sumo.routes=\"$routes\"" --set "sumo.cache=\"$tmp/cache\"")
    echo "$bare $record $fcd" >>"$tmp/rounds"
  done
  replay=$(for i in $(seq $repeat); do
    wall "$ncosim" run "$here/sumo_grid.toml" --quiet --out "$tmp/out" --set "sumo.routes=\"$routes\"" \
      --set "sumo.cache=\"$tmp/cache\"" --runs 100
  done | median)
  live=$(for i in $(seq $repeat); do
    wall "$ncosim" run "$here/sumo_grid.toml" --quiet --out "$tmp/out" --set "sumo.routes=\"$routes\"" \
      --set "sumo.cache=\"$tmp/cache\"" --set 'sumo.mode="live"' --runs 4
  done | median)
  python3 - "$n" "$tmp/rounds" "$replay" "$live" <<'PY'
import statistics, sys
n, rounds = sys.argv[1], [tuple(map(float, l.split())) for l in open(sys.argv[2])]
replay, live = map(float, sys.argv[3:])
def med(f):
    return statistics.median(f(r) for r in rounds)
# rounds: bare_wall bare_cpu record_wall record_cpu fcd_wall fcd_cpu
bare, record, fcd = med(lambda r: r[0]), med(lambda r: r[2]), med(lambda r: r[4])
ratio, fcd_ratio = med(lambda r: r[2] / r[0]), med(lambda r: r[4] / r[0])
cpu_ratio, cpu_fcd_ratio = med(lambda r: r[3] / r[1]), med(lambda r: r[5] / r[1])
ratios = " ".join(f"{r[2] / r[0]:.2f}" for r in rounds)
cpu_ratios = " ".join(f"{r[3] / r[1]:.2f}" for r in rounds)
# Each command also replays run 0 once more to time the estimators (ns_per_period): 101 and 5 runs.
per_replay, per_live = replay / 101, live / 5
print(f"grid {n:>4} vehicles: bare sumo {bare:.3f} s | recording pass {record:.3f} s | record/bare, median of "
      f"{len(rounds)} rounds: wall {ratio:.2f}x (rounds: {ratios}), CPU {cpu_ratio:.2f}x (rounds: {cpu_ratios}) | "
      f"sumo with the FCD output alone {fcd:.3f} s: wall {fcd_ratio:.2f}x, CPU {cpu_fcd_ratio:.2f}x bare\n  replay {per_replay * 1e3:.1f} ms/run "
      f"(100 runs: {replay:.3f} s) | live {per_live:.3f} s/run | live/replay per run {per_live / per_replay:.0f}x")
PY
done
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
