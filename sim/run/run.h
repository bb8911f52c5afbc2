// sim/run/run.h — one Monte Carlo run: the kernel's event queue routing between the run's
// components: the plant process, the sensors (models/sensor_process.h), the links, the
// estimators, the controller (models/controller.h), the actuation path and the recorder
// (sim/run/run_recorder.h). Each event handler is a few lines that hand one component's output
// to the next; the components own their state and random streams.
#pragma once

#include <chrono>
#include <cstdint>
#include <vector>

#include "sim/run/run_results.h"
#include "sim/scenario/scenario_types.h"

namespace ncosim::sim {

// The first periods of one run as the estimators saw them, replayed to time each estimator
// alone. Bounded: the replay's memory and time do not grow with the periods of a run. The log
// takes about 400 bytes per period (base.toml, two sensors; vectors grown by doubling): at 10 000
// periods the peak RSS of one run was 16 % higher at 10^7 periods than at 10^5 (whose log is
// 2 % of its periods, 2000), at 5000 still 13 %; at 2000 every run of 10^5 periods or more logs
// the same (Reliability.PeakMemoryOfARunDoesNotGrowWithItsPeriods).
inline constexpr std::size_t kReplayPeriods = 2000;
struct ReplayLog {
  std::vector<est::Packet> packets;
  std::vector<std::int64_t> packet_period;
  std::vector<Eigen::VectorXd> u, drive;  // per period
  std::size_t limit = kReplayPeriods;     // periods logged
};

// Simulates run `run`; `trace`, `log`, `links` and `curve` (the error curve the run's errors are
// added to) are optional outputs.
RunMetrics execute_run(const Scenario& sc, std::uint64_t run, std::vector<TraceRow>* trace,
                       ReplayLog* log, std::vector<models::LinkCounters>* links,
                       ErrorCurve* curve = nullptr);

// Simulates run `run` and returns the fate of every packet sent over link `link` (a node of a
// [[network]]: its network decides the fates, with every other sender of the scenario
// contending), by period and within a period by sensor. After the last period the networks run on
// until every packet has a fate (at most 60 s of simulated time more; a packet still in the
// network then is lost).
std::vector<RecordedPacket> record_network_link(const Scenario& sc, std::uint64_t run,
                                                std::size_t link);

// Replays a logged run into a fresh instance of each estimator and times it alone: the median
// over repetitions of (wall time / periods). At least one repetition, at most 15, more only
// while the estimator's `budget` lasts.
std::vector<double> time_estimators(const Scenario& sc, const ReplayLog& log,
                                    std::chrono::nanoseconds budget);

}  // namespace ncosim::sim
