// sim/run/network_path.cc — one run's packet networks as the run engine uses them
// (sim/run/network_path.h).
#include "sim/run/network_path.h"

#include <algorithm>

#include "kernel/check.h"

namespace ncosim::sim {

std::unique_ptr<NetworkPath> NetworkPath::start(const Scenario& sc,
                                                const models::MobilityRun* mobility,
                                                std::uint64_t run) {
  if (sc.networks.empty()) return nullptr;
  return std::make_unique<NetworkPath>(sc, mobility, run);
}

// Every link that is a node of a network is a sender (in link order), then the [[background]]
// nodes, whose traffic stays inside the networks (counted, never a fate). An actuator's link (its
// own: the reader refuses one shared) sends downlink.
NetworkPath::NetworkPath(const Scenario& sc, const models::MobilityRun* mobility, std::uint64_t run)
    : sc_(sc), mobility_(mobility), period_ns_(kernel::seconds_to_time(sc.run.period)) {
  std::vector<network::Sender> senders;
  for (const auto& l : sc.links) {
    const models::NetworkAttachment* a = l.link->network_attachment();
    sender_.push_back(a != nullptr ? static_cast<int>(senders.size()) : -1);
    vehicle_.push_back(a != nullptr ? a->vehicle : -1);
    if (a != nullptr) senders.push_back(network::Sender{a->network, a->bytes, a->x, a->y, a->z});
  }
  for (const auto& am : sc.model.actuators) {
    const int l = am.spec.link;
    const int sender = l >= 0 ? sender_[static_cast<std::size_t>(l)] : -1;
    if (sender >= 0) senders[static_cast<std::size_t>(sender)].downlink = true;
    command_sender_.push_back(sender);
  }
  commanded_ =
      std::any_of(command_sender_.begin(), command_sender_.end(), [](int s) { return s >= 0; });
  if (commanded_) {
    command_.assign(command_sender_.size(), -1);
    arrived_.assign(command_sender_.size(), 0);
  } else {
    command_sender_.clear();
  }
  first_background_ = static_cast<int>(senders.size());
  run_ = sc.networks.start(std::move(senders), sc.run.seed, run);
}

void NetworkPath::move_nodes(kernel::SimTime now) {
  constexpr double kAntenna = 1.5;  // m above the road
  const auto place = [&](int vehicle, auto&& move) {
    const models::VehicleState& v = mobility_->vehicle(vehicle);
    move(v.x, v.y, v.present ? kAntenna : network::kAway);
  };
  for (std::size_t l = 0; l < sender_.size(); ++l) {
    if (vehicle_[l] < 0) continue;
    place(vehicle_[l],
          [&](double x, double y, double z) { run_->move_sender(sender_[l], x, y, z, now); });
  }
  const auto& background = sc_.networks.background();
  for (std::size_t b = 0; b < background.size(); ++b) {
    if (background[b].vehicle < 0) continue;
    place(background[b].vehicle, [&](double x, double y, double z) {
      run_->move_sender(first_background_ + static_cast<int>(b), x, y, z, now);
    });
  }
  for (std::size_t n = 0; n < sc_.networks.size(); ++n) {
    if (sc_.networks[n].sink_vehicle < 0) continue;
    place(sc_.networks[n].sink_vehicle, [&](double x, double y, double z) {
      run_->move_sink(static_cast<int>(n), x, y, z, now);
    });
  }
}

bool NetworkPath::in_traffic(int link) const {
  const int vehicle = vehicle_[static_cast<std::size_t>(link)];
  return vehicle < 0 || mobility_->vehicle(vehicle).present;
}

void NetworkPath::lost(int link, std::size_t sensor, std::int64_t k) {
  if (record_out_ != nullptr && link == record_link_)
    record_out_->push_back(RecordedPacket{k, sensor, models::kLost});
}

void NetworkPath::send(int link, std::size_t sensor, std::size_t id, std::int64_t k) {
  if (sent_.size() <= id) sent_.resize(id + 1);
  sent_[id] = Sent{k, -1};
  if (record_out_ != nullptr && link == record_link_) {
    sent_[id].record_row = static_cast<std::int64_t>(record_out_->size());
    record_out_->push_back(RecordedPacket{k, sensor, models::kLost});
    ++pending_;
  }
  run_->send(sender_[static_cast<std::size_t>(link)], id, k * period_ns_);
}

void NetworkPath::advance(kernel::SimTime now, const PacketFate& fate, models::ActuatorStage* stage,
                          bool count) {
  fates_.clear();
  run_->advance_to(now, fates_);
  now_ = now;
  for (const network::Fate& f : fates_) {
    const bool delivered = f.drop == network::Drop::kNone;
    const auto at = std::find(command_sender_.begin(), command_sender_.end(), f.sender);
    if (at != command_sender_.end()) {  // a command: counted, kept when in time for its period
      const auto a = static_cast<std::size_t>(at - command_sender_.begin());
      const auto k = static_cast<std::int64_t>(f.id);
      const std::int64_t delay = (f.time - k * period_ns_) / period_ns_;
      if (count) stage->counters()[a].record(delivered ? delay : models::kLost, -1);
      if (delivered && delay == 0 && command_[a] == k) arrived_[a] = 1;
      continue;
    }
    const auto id = static_cast<std::size_t>(f.id);
    Sent& s = sent_[id];
    const std::int64_t arrival = (f.time + period_ns_ - 1) / period_ns_;
    const std::int64_t delay = delivered ? arrival - s.period : models::kLost;
    if (s.record_row >= 0) {
      (*record_out_)[static_cast<std::size_t>(s.record_row)].delay = delay;
      s.record_row = -1;
      --pending_;
    }
    fate(id, delivered ? arrival : models::kLost);
  }
}

void NetworkPath::send_commands(std::int64_t k, kernel::SimTime now) {
  for (std::size_t a = 0; a < command_sender_.size(); ++a) {
    if (command_sender_[a] < 0) continue;
    run_->send(command_sender_[a], static_cast<std::uint64_t>(k), now);  // the id: its period
    command_[a] = k;
    arrived_[a] = 0;
  }
}

int NetworkPath::resolve_commands(std::int64_t k, models::ActuatorStage& stage) {
  int mode = 0;
  for (std::size_t a = 0; a < command_sender_.size(); ++a) {
    if (command_sender_[a] < 0 || command_[a] != k - 1) continue;
    mode |= stage.resolve(static_cast<int>(a), arrived_[a] != 0);
    command_[a] = -1;
  }
  return mode;
}

std::optional<models::StackCounters> NetworkPath::stack(int link) const {
  const int sender = link >= 0 ? sender_[static_cast<std::size_t>(link)] : -1;
  if (sender < 0) return std::nullopt;
  const network::MacCounters c = run_->counters(sender);
  models::StackCounters k;
  k.attempts = static_cast<std::int64_t>(c.attempts);
  k.retries = static_cast<std::int64_t>(c.retries);
  for (const std::uint64_t d : c.dropped) k.drops.push_back(static_cast<std::int64_t>(d));
  k.busy_ns = c.busy_ns;
  k.simulated_ns = now_;
  return k;
}

void NetworkPath::drain(kernel::SimTime period_ns) {
  // Up to 60 s, in steps of a period but at least 1 ms: a fate carries its own time, so the step
  // changes no delay, and a period of 1 ns would otherwise take 6e10 steps.
  constexpr kernel::SimTime kDrainNs = 60'000'000'000, kLeastStepNs = 1'000'000;
  const kernel::SimTime end = now_ + kDrainNs, step = std::max(period_ns, kLeastStepNs);
  for (kernel::SimTime t = now_ + step; pending_ > 0 && t <= end; t += step)
    advance(
        t, [](std::size_t, std::int64_t) {}, nullptr, false);
}

}  // namespace ncosim::sim
