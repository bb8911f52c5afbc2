// models/packet.h — what a sensor sends and a link delivers: samples of one sensor, newest
// first, with their sampling periods. Made by the sensors of a run (models/sensor_process.h),
// carried by the links, read by the estimators (estimators/estimator.h).
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <vector>

namespace ncosim::models {

struct Packet {
  int sensor = -1;
  std::int64_t send_period = 0;
  int count = 0;                     // number of samples
  std::vector<std::int64_t> stamps;  // stamps[i] = sampling period of sample i
  Eigen::VectorXd values;            // sample i occupies rows [i*ny, (i+1)*ny)
  // A copy from an independent-copies link (the design model of Dolz Remark 2.3): it carries
  // its own measurement noise, so it is a new measurement even if its sample was seen before.
  bool independent_copy = false;
};

}  // namespace ncosim::models
