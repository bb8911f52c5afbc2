// models/sensor.h — sensors: y = C x + v, v ~ N(0, R) (or bounded: uniform with covariance
// R), sampled every `every` periods; each packet carries the newest sample and the `buffer`
// previous ones, with their time stamps. Policy "periodic" sends every sample; policy
// "send_on_delta" sends a sample only when |y_i - y_i(last sent)| >= delta_i for some
// output i (the first sample is always sent).
#pragma once

#include <Eigen/Dense>
#include <string>
#include <vector>

#include "config/config.h"
#include "models/plant.h"

namespace ncosim::models {

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
  enum class Policy { kPeriodic, kSendOnDelta };
  Policy policy = Policy::kPeriodic;
  Eigen::VectorXd delta;  // send_on_delta: threshold per output (ny), >= 0
  enum class Noise { kGaussian, kUniform };
  Noise noise = Noise::kGaussian;  // uniform: v_i ~ U(-sqrt(3 R_ii), sqrt(3 R_ii)), R diagonal
  Eigen::Index ny() const { return C.rows(); }
};

// Reads one [[sensor]] table; `links` are the scenario's link names (for `link`).
// The optional `link` key of a sensor or actuator table: the index of the named [[link]] in
// `links`, -1 when absent (ideal link); an unknown name fails with the list and a suggestion.
int read_link_ref(const sim::Table& t, const std::vector<std::string>& links);

SensorSpec read_sensor(const sim::Table& t, const LinearPlant& plant,
                       const std::vector<std::string>& links, int index);

}  // namespace ncosim::models
