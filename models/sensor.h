// models/sensor.h — sensors: y = C x + v, v ~ N(0, R), sampled every `every` periods; each
// packet carries the newest sample and the `buffer` previous ones, with their time stamps.
#pragma once

#include <Eigen/Dense>
#include <string>
#include <vector>

#include "models/plant.h"
#include "sim/config.h"

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
  Eigen::Index ny() const { return C.rows(); }
};

// Reads one [[sensor]] table; `links` are the scenario's link names (for `link`).
SensorSpec read_sensor(const sim::Table& t, const LinearPlant& plant,
                       const std::vector<std::string>& links, int index);

}  // namespace ncosim::models
