// models/sensor_process.h — one sensor of one run: its own noise stream, the ring of its last
// buffer + 1 samples (with their stamps) and its send policy's state. The run calls sample()
// at each sampling instant and, for each copy a link delivers, pack() to fill the packet.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <memory>
#include <vector>

#include "kernel/rng.h"
#include "models/packet.h"
#include "models/send_policy.h"
#include "models/sensor.h"

namespace ncosim::models {

class SensorProcess {
 public:
  // `index` numbers the sensor in the scenario (its stream and the packets' `sensor`).
  SensorProcess(const SensorSpec& spec, int index, std::uint64_t seed, std::uint64_t run);

  // Samples y[k] = C x + R^1/2 v (noise drawn from the sensor's stream) into the ring and asks
  // the policy; true when the sample is to be sent.
  bool sample(std::int64_t k, const Eigen::VectorXd& x);
  // The newest sample (ny).
  Eigen::MatrixXd::ConstColXpr newest() const { return values_.col(head_); }
  // The design model of an independent-copies link: the newest sample with a fresh noise draw.
  void redraw_newest(const Eigen::VectorXd& x);
  // Fills `p` with the ring's samples, newest first, as sent at period k.
  void pack(Packet& p, std::int64_t k, bool independent_copy);
  // What the receiver holds of each output when the policy skips samples (nullptr: it never does).
  const Eigen::VectorXd* held() const { return policy_->held(); }
  const SensorSpec& spec() const { return spec_; }

 private:
  const SensorSpec& spec_;
  int index_;
  kernel::Rng rng_;
  Eigen::MatrixXd r_sqrt_;
  Eigen::VectorXd noise_;
  std::vector<std::int64_t>
      stamps_;              // ring of the last buffer+1 sampling periods (newest at head_)
  Eigen::MatrixXd values_;  // column per ring slot
  Eigen::MatrixXd clean_;   // C x of each slot (resend_noise = "fresh" only)
  int head_ = -1;
  int filled_ = 0;
  std::unique_ptr<SendPolicy> policy_;
};

}  // namespace ncosim::models
