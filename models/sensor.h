// models/sensor.h — sensors: y = C x + v, v ~ N(0, R) (or bounded: uniform with covariance
// R), sampled every `every` periods; each packet carries the newest sample and the `buffer`
// previous ones, with their time stamps. When a sample is sent is the sensor's send policy
// (models/send_policy.h: "periodic", "send_on_delta", or a registered one).
#pragma once

#include <Eigen/Dense>
#include <memory>
#include <string>
#include <vector>

#include "config/config.h"
#include "config/keys.h"
#include "models/plant.h"
#include "models/send_policy.h"

namespace ncosim::models {

class MeasurementFunction;  // models/nonlinear.h

struct SensorSpec {
  std::string name;
  Eigen::MatrixXd C;  // ny x n
  Eigen::MatrixXd R;  // ny x ny, symmetric PSD
  int link = -1;      // index into the scenario's links; -1 = ideal (delay 0, never lost)
  int every = 1;      // samples at periods k with k % every == 0
  int buffer = 0;     // extra past samples per packet
  // resend_noise = "fresh": a sample re-sent in a later buffered packet carries a new noise
  // draw (the jump observer's design model for buffered packets); "same" (default): the
  // physical case, the sample's own noise every time.
  bool fresh_resend_noise = false;
  std::shared_ptr<const SendPolicyDesign> policy = periodic_policy();  // `policy` key
  enum class Noise { kGaussian, kUniform };
  Noise noise = Noise::kGaussian;  // uniform: v_i ~ U(-sqrt(3 R_ii), sqrt(3 R_ii)), R diagonal
  // Non-null for a nonlinear sensor (models/nonlinear.h): y = h(x, k) + v; C is then h's Jacobian
  // at the plant's x0.
  std::shared_ptr<const MeasurementFunction> h;
  Eigen::Index ny() const { return C.rows(); }
  // The send-on-delta thresholds (ny) when the policy is a send-on-delta dead band, else nullptr.
  const Eigen::VectorXd* deadband() const { return policy->deadband(); }
};

// The keys of a [[sensor]] table beside its send policy's (`ncosim list --keys section.sensor`).
const config::Keys& sensor_keys();

// The optional `link` key of a sensor or actuator table: the index of the named [[link]] in
// `links`, -1 when absent (ideal link); an unknown name fails with the list and a suggestion.
int read_link_ref(const config::KeyReader& t, const std::vector<std::string>& links);

// Reads one [[sensor]] table through sensor_keys(); `links` are the scenario's link names (for
// `link`).

SensorSpec read_sensor(const config::Table& t, const LinearPlant& plant,
                       const std::vector<std::string>& links, int index,
                       const SendPolicyRegistry& policies);

}  // namespace ncosim::models
