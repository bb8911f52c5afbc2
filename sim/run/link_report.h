// sim/run/link_report.h — links.csv: what every link did to the packets of every sender, summed
// over the runs of a case, beside what the link's model predicts (models/link_stats.h).
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "models/link_stats.h"
#include "sim/run/run_results.h"
#include "sim/run/trend.h"
#include "sim/scenario/scenario.h"

namespace ncosim::sim {

// One (link, sender) pair. Order: by link, then the sensors naming it (sensor order), then the
// actuators naming it (actuator order). Ideal senders (no link) have no flow.
struct LinkFlow {
  std::size_t link = 0;
  bool actuator = false;
  std::size_t sender = 0;  // sensor or actuator index
  std::string sender_name;
  bool sole = true;  // the only sender on this link instance (actuators: always)
  // Channel steps between two consecutive packets of this sender when regular (1 per packet for
  // a sole sender on a per-packet link; the sender's `every` on a per-period link);
  // nullopt when irregular (senders interleaving on a per-packet chain, send-on-delta on a
  // per-period chain).
  std::optional<int> gap;
  std::string step;  // "period" or "packet" when the link has a state that moves
                     // (Link::state_step), "" otherwise
};
std::vector<LinkFlow> link_flows(const Scenario& sc);

// The flow index of each sensor and of each actuator (-1: ideal).
struct FlowIndex {
  std::vector<int> sensor, actuator;
};
FlowIndex flow_index(const Scenario& sc, const std::vector<LinkFlow>& flows);

// Overload told (results/README.md, "Overload and growth"): each flow's delays and losses in the
// order they were counted, as block means per run (models::DelayBlocks), tested for a growth
// through the run (sim/run/trend.h), one-sided at kTrendAlpha each.
inline constexpr double kTrendAlpha = 0.001;  // a false alarm in 1000 campaigns, per test
// A growth is told only when it is also material: the fitted mean delay grows by at least
// kMinDelayGrowth periods over the run, the fitted loss ratio by kMinLossGrowth.
inline constexpr double kMinDelayGrowth = 1.0;
inline constexpr double kMinLossGrowth = 0.05;
// A run with fewer blocks (holding a delivered packet, for delays) is not in the test.
inline constexpr std::size_t kMinTrendBlocks = 16;

struct FlowLoad {
  double offered_rate = 0.0;    // packets the sender handed to the link per period, over the runs
  double delivered_rate = 0.0;  // packets delivered per period
  bool queue = false;           // the link's queue can grow (a node of a [[network]])
  // The trends of the mean delay of delivered packets and of the loss ratio; nullopt: too few
  // blocks to test.
  std::optional<TrendResult> delay, loss;
  // "" (neither tested), "none", "trend" or "overloaded": a queue link falling behind its offered
  // rate while its delays grow.
  std::string verdict;
};

// One per flow of `flows` (link_flows(sc)), from the runs' link counters (res.link_runs) and the
// sensors' sent samples (res.runs).
std::vector<FlowLoad> flow_loads(const Scenario& sc, const CampaignResult& res,
                                 const std::vector<LinkFlow>& flows);

// One row per case and flow; columns in results/README.md.
std::string links_csv(const std::vector<SweepAxis>& sweeps,
                      const std::vector<std::vector<std::string>>& labels,
                      const std::vector<const Scenario*>& scenarios,
                      const std::vector<const CampaignResult*>& results);

}  // namespace ncosim::sim
