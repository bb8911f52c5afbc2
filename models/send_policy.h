// models/send_policy.h — when a sensor sends: the `policy` key of a [[sensor]] table names an
// entry of the send-policy registry. A SendPolicyDesign is read once per scenario (shared
// read-only by every run); instantiate() makes the per-run SendPolicy, which keeps its own
// state (the value last sent). Built in: "periodic" (every sample) and "send_on_delta" (a
// sample only when |y_i - y_i(last sent)| >= delta_i for some output i; the first sample is
// always sent). A new policy is one class pair and one registration line (docs/extending.md).
#pragma once

#include <Eigen/Dense>
#include <memory>
#include <string>

#include "config/config.h"
#include "config/registry.h"

namespace ncosim::models {

struct SensorSpec;

class SendPolicy {
 public:
  virtual ~SendPolicy() = default;
  // Whether the sensor sends its newest sample (ny entries, taken at this period).
  virtual bool decide(const Eigen::Ref<const Eigen::VectorXd>& sample) = 0;
  // The value of each output that the receiver holds (the last sample sent), for the error of
  // the samples not sent (transmissions.csv, `virtual_noise_rms`); nullptr for a policy that sends
  // every sample.
  virtual const Eigen::VectorXd* held() const { return nullptr; }
};

class SendPolicyDesign {
 public:
  virtual ~SendPolicyDesign() = default;
  virtual std::unique_ptr<SendPolicy> instantiate() const = 0;
  // The registered name (transmissions.csv `policy`).
  virtual std::string name() const = 0;
  // True when every sample is sent: the sensor's link then sees one packet every `every`
  // periods, and what arrives does not depend on the state.
  virtual bool sends_every_sample() const { return false; }
  // The per-output thresholds delta (ny) of a send-on-delta dead band, the event model that the
  // send-on-delta estimators design for (sod_jump, sod_kalman, sod_hold); nullptr otherwise.
  virtual const Eigen::VectorXd* deadband() const { return nullptr; }
};

// Factories read the policy's keys from the [[sensor]] table; the SensorSpec holds what was
// read before the policy (C, R, every, buffer).
using SendPolicyRegistry =
    config::Registry<std::shared_ptr<const SendPolicyDesign>, const SensorSpec&>;
void register_send_policies(SendPolicyRegistry& registry);

// The built-in periodic policy (the default of every sensor).
std::shared_ptr<const SendPolicyDesign> periodic_policy();

}  // namespace ncosim::models
