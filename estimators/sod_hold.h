// estimators/sod_hold.h — the estimator side of send-on-delta sensors: the held measurement
// vector m (newest value received from each sensor, stacked over the sensors' outputs) and which
// sensors sent a sample of the current period (alpha_i = 1 in the send-on-delta paper, eq. (5)).
// A late packet (sample older than the period) refreshes m when it is the newest seen, but
// does not count as a new measurement.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <vector>

#include "estimators/estimator.h"

namespace ncosim::est {

class SodHold {
 public:
  explicit SodHold(const Model& model) {
    Eigen::Index off = 0;
    for (const auto& s : model.sensors) {
      offset_.push_back(off);
      ny_.push_back(s.spec.ny());
      off += s.spec.ny();
    }
    m_ = Eigen::VectorXd::Zero(off);
    stamp_.assign(model.sensors.size(), -1);
  }

  // Returns 1 when the packet's newest sample is newer than the one held.
  int accept(const Packet& p, std::int64_t k) {
    const auto s = static_cast<std::size_t>(p.sensor);
    if (p.count == 0 || p.stamps[0] <= stamp_[s]) return 0;
    stamp_[s] = p.stamps[0];
    m_.segment(offset_[s], ny_[s]) = p.values.head(ny_[s]);
    if (p.stamps[0] == k) pattern_ |= std::uint64_t{1} << s;
    return 1;
  }
  // Sensors (bit s) with a new sample this period; cleared by clear_pattern().
  std::uint64_t pattern() const { return pattern_; }
  void clear_pattern() { pattern_ = 0; }
  bool ever(std::size_t s) const { return stamp_[s] >= 0; }
  const Eigen::VectorXd& m() const { return m_; }
  Eigen::Index offset(std::size_t s) const { return offset_[s]; }
  Eigen::Index ny(std::size_t s) const { return ny_[s]; }
  std::size_t sensors() const { return ny_.size(); }

 private:
  std::vector<Eigen::Index> offset_, ny_;
  std::vector<std::int64_t> stamp_;
  Eigen::VectorXd m_;
  std::uint64_t pattern_ = 0;
};

// The stacked output matrix and noise covariance (block diagonal) of the model's sensors.
inline void stacked_outputs(const Model& model, Eigen::MatrixXd& C, Eigen::MatrixXd& R) {
  const Eigen::Index ny = model.total_outputs();
  C.resize(ny, model.plant.n());
  R = Eigen::MatrixXd::Zero(ny, ny);
  Eigen::Index off = 0;
  for (const auto& s : model.sensors) {
    C.middleRows(off, s.spec.ny()) = s.spec.C;
    R.block(off, off, s.spec.ny(), s.spec.ny()) = s.spec.R;
    off += s.spec.ny();
  }
}

// The send-on-delta thresholds of the stacked outputs (0 for periodic sensors).
inline Eigen::VectorXd stacked_delta(const Model& model) {
  Eigen::VectorXd d = Eigen::VectorXd::Zero(model.total_outputs());
  Eigen::Index off = 0;
  for (const auto& s : model.sensors) {
    if (const Eigen::VectorXd* delta = s.spec.deadband()) d.segment(off, s.spec.ny()) = *delta;
    off += s.spec.ny();
  }
  return d;
}

}  // namespace ncosim::est
