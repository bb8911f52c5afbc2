// tests/cli/small_trace_scenario.h — a small scenario whose one link replays a trace file
// (`trace.csv` beside it), shared by the CLI tests of hostile input and of the run store.
#pragma once

#include <fmt/format.h>

#include <string>

namespace ncosim::testing {

inline const std::string kSmallTraceScenario = R"(title = "small"
[run]
periods = 200
warmup = 10
runs = 2
seed = 3
[plant]
kind = "lti"
A = [[0.9, 0.1], [0.0, 0.8]]
Bw = [[1.0, 0.0], [0.0, 1.0]]
W = [[0.1, 0.0], [0.0, 0.1]]
[[sensor]]
name = "y1"
C = [[1.0, 0.0]]
R = [[0.01]]
link = "net"
[[link]]
name = "net"
kind = "trace"
file = "trace.csv"
[[estimator]]
name = "kf"
kind = "kalman_extended"
max_delay = 1
)";

// `packets` rows `seq,delay`: every `lost_every`-th packet lost, the others delayed one period.
inline std::string small_trace_csv(int packets, int lost_every = 3) {
  std::string t = "seq,delay\n";
  for (int i = 0; i < packets; ++i) t += fmt::format("{},{}\n", i, i % lost_every == 0 ? "" : "1");
  return t;
}

}  // namespace ncosim::testing
