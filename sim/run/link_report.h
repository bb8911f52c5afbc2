// sim/run/link_report.h — links.csv: what every link did to the packets of every sender, summed
// over the runs of a case, beside what the link's model predicts (models/link_stats.h).
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "models/link_stats.h"
#include "sim/run/run_results.h"
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

// One row per case and flow; columns in results/README.md.
std::string links_csv(const std::vector<SweepAxis>& sweeps,
                      const std::vector<std::vector<std::string>>& labels,
                      const std::vector<const Scenario*>& scenarios,
                      const std::vector<const CampaignResult*>& results);

}  // namespace ncosim::sim
