// sim/run/error_curve.h — the run-averaged squared error against time ([run] error_curve = true):
// per period k and estimator, the mean over the runs of |x[k] - xhat[k]|^2 with its 95 % band,
// and the mean of each state's squared error. Computed on the fly, never by keeping runs: each
// worker thread adds its runs into its own ErrorCurve (O(periods x estimators x (n + 1))
// memory), and curves merge by addition (threads, sessions of a resumed campaign, shards).
//
// Order: every cell is a compensated sum (hi + lo, Knuth's TwoSum), whose error is about
// runs^2 x 2^-106 of the sum, far below the last digit of a double; the exported means and
// bands (6 significant digits) therefore do not depend on which thread, session or shard added
// which run, although the stored (hi, lo) pairs may.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <string>
#include <vector>

#include "sim/scenario/scenario_types.h"

namespace ncosim::sim {

class ErrorCurve {
 public:
  ErrorCurve() = default;
  ErrorCurve(std::int64_t periods, std::size_t estimators, Eigen::Index n);

  bool empty() const { return periods_ == 0; }
  std::int64_t periods() const { return periods_; }
  std::size_t estimators() const { return estimators_; }
  Eigen::Index states() const { return n_; }

  // Run-time path: estimator e's error x[k] - xhat[k] (n) at period k of the current run.
  void add(std::int64_t k, std::size_t e, const double* err) {
    double* s = sums_.data() + 2 * cell(k, e, 0);
    double total = 0.0;
    for (Eigen::Index i = 0; i < n_; ++i, s += 2) {
      const double v = err[i] * err[i];
      total += v;
      add_to(s[0], s[1], v);
    }
    add_to(s[0], s[1], total * total);
  }
  // Marks run `run` as added (once per run, after its last period).
  void add_run(std::uint64_t run) { runs_.push_back(run); }
  // Adds another curve of the same shape (its runs must be disjoint from these); an empty curve
  // takes the other's sums (moved when given an rvalue).
  void merge(const ErrorCurve& other);
  void merge(ErrorCurve&& other);

  // The runs added, in the order they were added.
  const std::vector<std::uint64_t>& runs() const { return runs_; }
  // Means over the runs added: of estimator e's squared error (sum over the states) and of state
  // i's; the half-width of the 95 % confidence interval of the first (Student t, runs - 1).
  double mean(std::int64_t k, std::size_t e) const;
  double mean_state(std::int64_t k, std::size_t e, Eigen::Index i) const;
  double ci95(std::int64_t k, std::size_t e) const;

  // Exact binary form (doubles by their bits); deserialize throws std::runtime_error on a
  // malformed blob.
  std::string serialize() const;
  static ErrorCurve deserialize(const std::string& blob);

 private:
  std::size_t cell(std::int64_t k, std::size_t e, Eigen::Index c) const {
    return (static_cast<std::size_t>(k) * estimators_ + e) * static_cast<std::size_t>(n_ + 1) +
           static_cast<std::size_t>(c);
  }
  double value(std::size_t c) const { return sums_[2 * c] + sums_[2 * c + 1]; }
  // Knuth's TwoSum: hi + v = s + err exactly; the rounding error is kept in lo.
  static void add_to(double& hi, double& lo, double v) {
    const double s = hi + v;
    const double bv = s - hi;
    const double err = (hi - (s - bv)) + (v - bv);
    hi = s;
    lo += err;
  }

  std::int64_t periods_ = 0;
  std::size_t estimators_ = 0;
  Eigen::Index n_ = 0;
  // Per (k, e): n cells of squared state errors, then one of the squared total (for the band);
  // each cell a pair (hi, lo) side by side.
  std::vector<double> sums_;
  std::vector<std::uint64_t> runs_;
  // ci95() caches the Student t quantile of the current run count (not for concurrent calls).
  mutable std::size_t t_runs_ = 0;
  mutable double t975_ = 0.0;
};

// error_curve.csv ([run] error_curve): per case, estimator and period, the run-averaged squared
// error with its 95 % CI half-width and per state (sim/run/error_curve.h); curves[c] of case c.
std::string error_curve_csv(const std::vector<SweepAxis>& sweeps,
                            const std::vector<std::vector<std::string>>& labels,
                            const std::vector<const Scenario*>& scenarios,
                            const std::vector<ErrorCurve>& curves);

}  // namespace ncosim::sim
