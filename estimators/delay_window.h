// estimators/delay_window.h — bookkeeping shared by the delay-extended estimators: which
// (sensor, delay) samples arrived for the update of period k, their values, and which samples
// were already used. With `deduplicate` (the Kalman filter: a repeat would count the same
// noise twice) a buffered sample arriving again is ignored; without it (the jump observer,
// whose design model lets a buffered packet deliver every fictitious sensor it carries,
// Dolz example 3) every in-window sample of a packet is used.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <vector>

#include "estimators/estimator.h"
#include "estimators/extended_model.h"

namespace ncosim::est {

class DelayWindow {
 public:
  DelayWindow(const ExtendedModel& ext, bool deduplicate)
      : ext_(&ext),
        deduplicate_(deduplicate),
        seen_(static_cast<std::size_t>(ext.sensors), 0),
        values_(Eigen::VectorXd::Zero(ext.nmb)) {}

  // Records the samples of `p` usable at period k; returns how many of them are samples
  // (or independent copies) not seen before, for delivered_ratio.
  int accept(const Packet& p, std::int64_t k) {
    advance(k);
    const Eigen::Index ny = ext_->fict[ext_->index(p.sensor, 0)].rows;
    int used = 0;
    for (int i = 0; i < p.count; ++i) {
      const std::int64_t d = k - p.stamps[i];
      if (d < 0 || d > ext_->dbar) continue;
      const std::uint64_t bit = std::uint64_t{1} << d;
      std::uint64_t& seen = seen_[static_cast<std::size_t>(p.sensor)];
      const bool fresh = !(seen & bit) || p.independent_copy;
      if (!fresh && deduplicate_) continue;  // a sample already used
      seen |= bit;
      const int j = ext_->index(p.sensor, static_cast<int>(d));
      values_.segment(ext_->fict[j].row, ny) = p.values.segment(i * ny, ny);
      pattern_ |= std::uint64_t{1} << j;
      used += fresh ? 1 : 0;
    }
    return used;
  }

  // Moves the window to period k (bit d of seen_ = sample k - d already used).
  void advance(std::int64_t k) {
    if (k == period_) return;
    const std::int64_t shift = k - period_;
    for (auto& s : seen_) s = shift >= 64 ? 0 : (s << shift);
    period_ = k;
  }

  std::uint64_t pattern() const { return pattern_; }
  const Eigen::VectorXd& values() const { return values_; }
  void clear_pattern() { pattern_ = 0; }

 private:
  const ExtendedModel* ext_;
  bool deduplicate_;
  std::vector<std::uint64_t> seen_;
  Eigen::VectorXd values_;
  std::uint64_t pattern_ = 0;
  std::int64_t period_ = 0;
};

}  // namespace ncosim::est
