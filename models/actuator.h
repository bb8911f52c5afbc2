// models/actuator.h — controller-to-actuator links: one [[actuator]] per input channel.
// The command u_i[k] sent at period k crosses its link; if it arrives within the period
// (delay 0) the actuator applies it, otherwise (lost or late) it applies 0 (`on_loss = "zero"`)
// or keeps the last applied value (`"hold"`, u0 before the first delivery). The delivery
// pattern of a period is the mode theta[k] (Moayedi et al., eq. 5, Table 1 order).
// Bad tables raise ScenarioError from read_actuator().
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "config/config.h"
#include "config/keys.h"
#include "kernel/rng.h"
#include "models/link.h"
#include "models/link_stats.h"

namespace ncosim::models {

struct ActuatorSpec {
  enum class OnLoss { kHold, kZero };
  std::string name;
  int link = -1;  // index into the scenario's links; -1 = ideal (always delivered)
  OnLoss on_loss = OnLoss::kHold;
  double u0 = 0.0;  // the value held before period 0 (hold)
};

// The keys of an [[actuator]] table (`ncosim list --keys section.actuator`).
const config::Keys& actuator_keys();

// Reads one [[actuator]] table through actuator_keys(); `links` are the scenario's link names.
ActuatorSpec read_actuator(const config::Table& t, const std::vector<std::string>& links,
                           int index);

// Mode index of a delivery pattern, 0-based in the paper's Table 1 order: channel 0 is the
// most significant bit and a bit is 1 for a loss, so 0 = every channel delivered and
// 2^r - 1 = every channel lost (r = 2: 0 = (delivered, delivered), 1 = (delivered, lost),
// 2 = (lost, delivered), 3 = (lost, lost)).
inline bool channel_delivered(int mode, int channel, int channels) {
  return ((mode >> (channels - 1 - channel)) & 1) == 0;
}

// The actuators of one run: a fresh instance of each actuator's link with its own random
// stream (two actuators naming the same [[link]] are independent channels of that kind).
class ActuatorStage {
 public:
  ActuatorStage(const std::vector<ActuatorSpec>& specs, const std::vector<const Link*>& links,
                std::uint64_t seed, std::uint64_t run);
  // Sends `sent` (one entry per channel) and updates applied(); returns the mode of the period.
  // A networked channel is left pending: its bit of the mode and its applied value come from
  // resolve().
  int actuate(const Eigen::VectorXd& sent);
  // Whether channel i's link is a node of a [[network]] (network/network.h): the run sends its
  // command through the network and, before the next plant step, says whether it arrived within
  // its period (resolve).
  bool networked(int i) const { return channels_[static_cast<std::size_t>(i)].networked; }
  // Channel i's command of the last actuate() arrived within its period (`delivered`) or not
  // (lost or late): applied() is updated; returns the channel's bit of that period's mode.
  int resolve(int i, bool delivered);
  const Eigen::VectorXd& applied() const { return applied_; }
  // Per channel: what its link did to the commands so far (ideal channels count nothing).
  std::vector<LinkCounters>& counters() { return counters_; }

 private:
  struct Channel {
    std::unique_ptr<Link> link;  // nullptr: ideal
    kernel::Rng rng;
    ActuatorSpec::OnLoss on_loss;
    bool networked = false;  // the run decides its deliveries (resolve)
    double pending = 0.0;    // networked: the command of the last actuate()
  };
  std::vector<Channel> channels_;
  std::vector<LinkCounters> counters_;
  std::int64_t period_ = 0;  // actuate() is called once per period, from period 0
  Eigen::VectorXd applied_;
};

}  // namespace ncosim::models
