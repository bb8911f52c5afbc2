// sim/run/run_recorder.h — what one run measures: the true-state history, the error sums of every
// estimator from the warm-up on, the sensors' sent/skipped samples, mode detection, and the
// optional per-period trace. The run (sim/run/run.cc) hands it each event's outcome.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <memory>
#include <vector>

#include "sim/run/run_results.h"
#include "sim/scenario/scenario_types.h"

namespace ncosim::sim {

class RunRecorder {
 public:
  using Estimators = std::vector<std::unique_ptr<est::Estimator>>;
  // `curve` (optional): the error curve every period's errors are added to ([run] error_curve).
  RunRecorder(const Scenario& sc, const Estimators& estimators, std::vector<TraceRow>* trace,
              ErrorCurve* curve = nullptr);

  // The true state moved to x[k] (k = 0: the plant's first state, every history slot).
  void on_state(std::int64_t k, const Eigen::VectorXd& x);
  // Sensor s took a sample at k; `held` is what the receiver holds when the sample is not sent.
  void on_sample(std::size_t s, std::int64_t k, bool sent,
                 const Eigen::Ref<const Eigen::VectorXd>& sample, const Eigen::VectorXd* held);
  // Estimator e took `used` samples of a packet delivered at k.
  void on_used(std::size_t e, std::int64_t k, int used) {
    if (k >= warmup_) metrics_[e].samples_used += used;
  }
  void on_arrival(int sensor) { ++arrivals_[static_cast<std::size_t>(sensor)]; }
  // End of period k: the errors of every estimator against x (mode: theta[k-1], -1 none).
  void on_period(std::int64_t k, const Eigen::VectorXd& x, int true_mode, const Eigen::VectorXd& u,
                 double reference);
  // The run's metrics, with every estimator's final status and counters.
  RunMetrics finish();

 private:
  void trace_row(std::int64_t k, const Eigen::VectorXd& x, int true_mode, const Eigen::VectorXd& u,
                 double reference);
  void score_modes(int true_mode);
  void score_consistency(EstimatorRunMetrics& m, const est::Estimator& e, Eigen::Index n);

  const Scenario& sc_;
  const Estimators& estimators_;
  std::vector<TraceRow>* trace_;
  ErrorCurve* curve_;
  std::int64_t warmup_;
  std::int64_t block_length_;  // periods per error block (0: #K < kErrorBlocks, no blocks)
  int mode_count_;
  std::vector<Eigen::VectorXd> history_;  // true x[k], x[k-1], ... (x[-j] = x0)
  std::vector<int> arrivals_;             // per sensor, this period
  Eigen::VectorXd err_;
  std::vector<double> chol_;  // Cholesky factor of the state block of a covariance (NEES)
  Eigen::VectorXd whitened_;  // L^-1 err_
  std::vector<est::Estimator::Innovations> nis_start_;  // per estimator: at the end of warm-up
  bool precision_lost_ = false;
  RunMetrics metrics_;
  EstimatorRunMetrics sensors_;  // only the sensor counts: the same for every estimator
};

}  // namespace ncosim::sim
