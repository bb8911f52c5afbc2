#!/bin/sh
# scenarios/sumo/make_inputs.sh — builds the SUMO inputs of the SUMO scenarios with SUMO's own
# tools (netgenerate, randomTrips.py, duarouter), with fixed seeds, into scenarios/sumo/gen/
# (not committed). Run once after `apt install sumo sumo-tools`; ncosim hashes the generated
# files, so re-running it (same SUMO version, same seeds) keeps the recordings valid.
#   highway.net.xml  10 km straight 3-lane motorway (33.33 m/s), nodes every 500 m
#   highway.rou.xml  background traffic (randomTrips seed 42, one trip every 1.5 s for 400 s)
#   platoon.rou.xml  the named vehicles: "leader" and receivers "ego2" .. "ego20" departing
#                    2 .. 20 s after it from the west end (all heading east)
#   grid.net.xml     4x4 grid, 200 m blocks, 1 lane, 13.89 m/s (benchmarks)
#   grid100.rou.xml, grid1000.rou.xml: 100 / 1000 random trips over 300 s (seeds 7 / 8)
set -eu
export SUMO_HOME="${SUMO_HOME:-/usr/share/sumo}"
here=$(cd "$(dirname "$0")" && pwd)
out="$here/gen"
mkdir -p "$out"
cd "$out"
tools="$SUMO_HOME/tools"
q() { "$@" >/dev/null 2>&1 || { echo "failed: $*" >&2; "$@"; exit 1; }; }

q netgenerate --grid --grid.x-number 21 --grid.y-number 1 --grid.x-length 500 \
  --default.lanenumber 3 --default.speed 33.33 --no-turnarounds true --seed 1 -o highway.net.xml
q python3 "$tools/randomTrips.py" -n highway.net.xml --seed 42 -b 0 -e 400 -p 1.5 \
  --fringe-factor 1000 --min-distance 4000 -o highway.trips.xml --validate
q duarouter -n highway.net.xml -r highway.trips.xml --seed 42 --no-warnings true -o highway.rou.xml
# The named vehicles: the west-most edge to the east-most edge of the motorway.
cat > platoon.rou.xml <<XML
<routes>
  <vType id="car" accel="2.6" decel="4.5" sigma="0.5" maxSpeed="33.33" speedFactor="normc(1,0.1,0.8,1.2)"/>
  <route id="eastbound" edges="A0B0 B0C0 C0D0 D0E0 E0F0 F0G0 G0H0 H0I0 I0J0 J0K0 K0L0 L0M0 M0N0 N0O0 O0P0 P0Q0 Q0R0 R0S0 S0T0 T0U0"/>
  <vehicle id="leader" type="car" route="eastbound" depart="20" departLane="best" departSpeed="max"/>
  <vehicle id="ego2" type="car" route="eastbound" depart="22" departLane="best" departSpeed="max"/>
  <vehicle id="ego5" type="car" route="eastbound" depart="25" departLane="best" departSpeed="max"/>
  <vehicle id="ego10" type="car" route="eastbound" depart="30" departLane="best" departSpeed="max"/>
  <vehicle id="ego20" type="car" route="eastbound" depart="40" departLane="best" departSpeed="max"/>

</routes>
XML

q netgenerate --grid --grid.number 4 --grid.length 200 --default.lanenumber 1 --default.speed 13.89 \
  --seed 1 -o grid.net.xml
for n in 100 1000; do
  seed=$([ "$n" = 100 ] && echo 7 || echo 8)
  period=$(python3 -c "print(300 / $n)")
  q python3 "$tools/randomTrips.py" -n grid.net.xml --seed "$seed" -b 0 -e 300 -p "$period" \
    -o "grid$n.trips.xml" --validate
  q duarouter -n grid.net.xml -r "grid$n.trips.xml" --seed "$seed" --no-warnings true -o "grid$n.rou.xml"
done
rm -f ./*.trips.xml ./*.alt.xml routes.rou.xml
echo "SUMO inputs written to $out"
