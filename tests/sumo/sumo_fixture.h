// tests/sumo/sumo_fixture.h — what the SUMO tests share: a straight two-lane road built with
// netconvert in a temporary folder, and the scenario text that drives a kalman-style estimator
// from a `sumo_vehicle` plant over one `sumo_distance` link named "v2v".
#pragma once

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace ncosim::testing {

// "leader" departs 100 m ahead at up to 30 m/s, "follower" behind it at up to 15 m/s.
inline constexpr const char* kLeaderAndFollower =
    R"(  <vehicle id="leader" type="fast" route="r" depart="0" departPos="100" departSpeed="max"/>
  <vehicle id="follower" type="slow" route="r" depart="0" departPos="0" departSpeed="max"/>
)";

// Writes into `dir` (created) a `length_m` long road from node a to node b (n.nod.xml,
// e.edg.xml), the routes file r.rou.xml (vehicle types "fast", "slow", route "r" and the
// `vehicles` lines) and net.net.xml by netconvert. True when netconvert succeeded.
inline bool write_sumo_road(const std::filesystem::path& dir, int length_m,
                            const std::string& vehicles) {
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "n.nod.xml") << R"(<nodes><node id="a" x="0" y="0"/><node id="b" x=")"
                                   << length_m << R"(" y="0"/></nodes>)";
  std::ofstream(dir / "e.edg.xml")
      << R"(<edges><edge id="ab" from="a" to="b" numLanes="2" speed="40"/></edges>)";
  std::ofstream(dir / "r.rou.xml") << R"(<routes>
  <vType id="fast" maxSpeed="30" sigma="0.5"/>
  <vType id="slow" maxSpeed="15" sigma="0.5"/>
  <route id="r" edges="ab"/>
)" << vehicles << "</routes>";
  const std::string cmd =
      "cd '" + dir.string() +
      "' && SUMO_HOME=/usr/share/sumo netconvert -n n.nod.xml -e e.edg.xml -o net.net.xml "
      ">/dev/null 2>&1";
  return std::system(cmd.c_str()) == 0;
}

// The scenario over that road (net.net.xml, r.rou.xml, step 0.1 s, recordings in "cache"): the
// plant follows "leader", one sensor reads position and speed over the link "v2v" from "leader"
// to `receiver` with the channel `preset`. `rest` follows the sensor (estimators, sweeps).
inline std::string sumo_scenario(int periods, int runs, int seeds, const std::string& receiver,
                                 const std::string& preset, const std::string& rest) {
  return "[run]\nperiods = " + std::to_string(periods) +
         "\nwarmup = 10\nruns = " + std::to_string(runs) +
         R"(
period = 0.1

[sumo]
net = "net.net.xml"
routes = "r.rou.xml"
step = 0.1
seeds = )" +
         std::to_string(seeds) +
         R"(
cache = "cache"

[plant]
kind = "sumo_vehicle"
vehicle = "leader"
model = "constant_velocity"
q = 1.0

[[link]]
name = "v2v"
kind = "sumo_distance"
sender = "leader"
receiver = ")" +
         receiver + R"("
preset = ")" +
         preset + R"("

[[sensor]]
C = [[1.0, 0.0], [0.0, 1.0]]
R = [[1.0, 0.0], [0.0, 0.01]]
link = "v2v"

)" + rest;
}

}  // namespace ncosim::testing
