// sim/run/network_path.h — one run's packet networks as the run engine (sim/run/run.cc) uses
// them: which links are nodes, their packets handed over and their fates read back in periods,
// the nodes that ride vehicles moved, the actuators' commands sent downlink, and what each node's
// MAC did (links.csv). The networks themselves are network::NetworkRun (network/backend.h),
// wherever they run (a worker process for ns-3); nothing here knows their engine.
//
// Lockstep: at the start of period k, after the period's sends, the networks run through every
// event at or before t = k T; a packet delivered in ((k - 1) T, k T] arrives at k T, before that
// period's estimator updates; a dropped one is lost.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "kernel/time.h"
#include "models/actuator.h"
#include "models/link_stats.h"
#include "models/mobility.h"
#include "network/backend.h"
#include "sim/run/run_results.h"
#include "sim/scenario/scenario.h"

namespace ncosim::sim {

class NetworkPath {
 public:
  // The networks of run `run` (nullptr when the scenario has none); `mobility` is the run's.
  static std::unique_ptr<NetworkPath> start(const Scenario& sc, const models::MobilityRun* mobility,
                                            std::uint64_t run);
  NetworkPath(const Scenario& sc, const models::MobilityRun* mobility, std::uint64_t run);

  // Whether link l is a node of a network (its packets go through send).
  bool carries(int link) const { return sender_[static_cast<std::size_t>(link)] >= 0; }
  // Whether an actuator's link is a node (commands go through send_commands).
  bool commands() const { return commanded_; }

  // At period k's start, before its sends: the nodes that ride vehicles are where their vehicles
  // are (a vehicle not in the traffic puts its node out of everyone's range, network::kAway).
  void move_nodes(kernel::SimTime now);
  // Whether link `link`'s node can send now: false while its vehicle is not in the traffic.
  bool in_traffic(int link) const;
  // Sensor `sensor`'s packet `id` of period k over link `link`, handed to the network at k T.
  void send(int link, std::size_t sensor, std::size_t id, std::int64_t k);
  // The same packet lost at once, never handed over (its node's vehicle is not in the traffic).
  void lost(int link, std::size_t sensor, std::int64_t k);
  // The networks through `now`: `fate(id, arrival)` for each sensor packet decided, in the order
  // the networks decided them: the period it arrives in (models::kLost when dropped). Commands'
  // fates are kept for resolve_commands (counted in `stage` when `count`).
  using PacketFate = std::function<void(std::size_t id, std::int64_t arrival)>;
  void advance(kernel::SimTime now, const PacketFate& fate, models::ActuatorStage* stage,
               bool count);

  // Actuators: channel a's command of period k is a packet sent at the close of period k (after
  // the control law); it is applied if it reaches the actuator's node before (k + 1) T, the next
  // plant step (phase order: the plant steps first at (k + 1) T, so a command received exactly
  // then is late, as a sample received then is used after that step).
  void send_commands(std::int64_t k, kernel::SimTime now);
  // Before the plant step of period k: the commands of period k - 1, applied or not; returns the
  // delivery pattern's bits (models::ActuatorStage::resolve).
  int resolve_commands(std::int64_t k, models::ActuatorStage& stage);

  // What link `link`'s node's stack did in the run (nullopt: not a node, or -1: no link).
  std::optional<models::StackCounters> stack(int link) const;

  // record-link: the fate of every packet that link `link`'s sensors send is written into `out`
  // (one row per packet, in send order), instead of being counted.
  void record(int link, std::vector<RecordedPacket>* out) {
    record_link_ = link;
    record_out_ = out;
  }
  // After the run's last period the networks go on (nothing else does) until every recorded packet
  // has its fate, for at most 60 s of simulated time.
  void drain(kernel::SimTime period_ns);

 private:
  struct Sent {  // a sensor packet handed to a network
    std::int64_t period = 0;
    std::int64_t record_row = -1;  // its row in record_out_, or -1
  };

  const Scenario& sc_;
  const models::MobilityRun* mobility_;
  kernel::SimTime period_ns_;
  std::unique_ptr<network::NetworkRun> run_;
  std::vector<int> sender_;   // per link: its network sender, or -1
  std::vector<int> vehicle_;  // per link: the vehicle its node rides, or -1
  int first_background_ = 0;  // the run's index of the first [[background]] node
  kernel::SimTime now_ = 0;   // where the networks are (their last advance_to)
  std::vector<network::Fate> fates_;
  std::vector<Sent> sent_;  // per pool packet id
  int record_link_ = -1;
  std::vector<RecordedPacket>* record_out_ = nullptr;
  std::int64_t pending_ = 0;  // recorded packets without a fate yet
  // Actuators over the networks.
  bool commanded_ = false;
  std::vector<int> command_sender_;    // per channel: its network sender, -1 (empty: none)
  std::vector<std::int64_t> command_;  // per channel: the period of its command in flight, or -1
  std::vector<char> arrived_;          // per channel: that command arrived in time
};

}  // namespace ncosim::sim
