// models/fit_internal.h — the machinery of models/fit.cc that the fit families
// (models/fit_families.cc) use: EM fits of hidden chains, Wald, likelihood-ratio and binomial
// intervals (models/fit_intervals.cc), the goodness of fit and the number formats of the written
// [[link]]. Not part of the models API.
#pragma once

#include <Eigen/Dense>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "models/fit.h"

namespace ncosim::models::fit_detail {

struct EmOutcome {
  FateHmm hmm;
  double loglik = 0.0;
  int iterations = 0;
  bool converged = false;
};

// The free coordinates of a model: in every row of `transition` and `emission`, the entries
// other than the largest (the largest is 1 - the others); zero entries stay fixed at 0.
struct Coordinates {
  struct Entry {
    bool emission;
    Eigen::Index row, col, dependent;
  };
  std::vector<Entry> entries;
};

int alphabet(const std::vector<int>& sym);
// Loss runs of the trace: runs[L - 1] = number of maximal runs of L losses.
std::vector<std::int64_t> loss_runs(const std::vector<int>& sym);
// A K-state chain fitted by Baum–Welch from o.starts starts (the best one).
EmOutcome fit_hidden(int K, const std::vector<int>& sym, const FitOptions& o, int& starts_used,
                     double mean_burst);
Coordinates free_coordinates(const FateHmm& h);
FateHmm moved(const FateHmm& h, const Coordinates& c, const Eigen::VectorXd& delta);
// Scaled forward-backward (models/fit.cc): the log-likelihood of `sym` under `h` and, when A and
// B are given, the expected transition (K x K) and emission (K x M) counts given the trace.
double e_step(const FateHmm& h, const std::vector<int>& sym, Eigen::MatrixXd* A, Eigen::MatrixXd* B,
              std::vector<double>& alpha, std::vector<double>& scale);

// ---- intervals (models/fit_intervals.cc) ----
// The covariance of the free coordinates (inverse observed information) by central differences
// of the exact log-likelihood (O(F^2) likelihoods); empty when singular.
Eigen::MatrixXd covariance(const FateHmm& h, const Coordinates& c, const std::vector<int>& sym);
// The same by central differences of the score (Fisher's identity: the E-step's expected counts;
// the stationary start's share, O(1) against O(N), left out): O(F) E-steps, for many
// coordinates. Empty when singular.
Eigen::MatrixXd covariance_from_scores(const FateHmm& h, const Coordinates& c,
                                       const std::vector<int>& sym);
// The covariance of a hidden family's free coordinates, by whichever of the two above fits the
// model's size; empty with `why` set when it is singular or too costly to compute.
Eigen::MatrixXd hidden_covariance(const FateHmm& h, const Coordinates& c,
                                  const std::vector<int>& sym, std::string& why);
// A probability estimated as x / n: its exact (Clopper–Pearson) 95 % interval.
FitParameter binomial(const std::string& name, double p, double n);
// The mean of `count[d]` packets of delay d: its normal 95 % interval (none when n < 2 or every
// delay is the same: `note` says so).
FitParameter mean_delay(const std::string& name, const std::vector<double>& count);
// A parameter whose Wald interval came out degenerate (a probability the fit put at 0 or 1, where
// the observed information says nothing): the likelihood-ratio bound of entry (row, col) of the
// transition (emission = false) or emission matrix, the other free entries held at their
// estimates; `scale` maps the entry to the parameter (e.g. 1 / P(delivered) for a conditional
// delay law). Leaves `p` without interval (and a note) when no bound can be found.
void likelihood_ratio_interval(FitParameter& p, const FateHmm& h, bool emission, Eigen::Index row,
                               Eigen::Index col, const std::vector<int>& sym, double scale = 1.0);
std::string num(double v);
std::string list(const std::vector<double>& v);
// A probability vector normalised to sum to 1.
std::vector<double> law(std::vector<double> v);
void goodness_of_fit(FitResult& r, const std::vector<int>& sym, int lags);

// A reported quantity of the model and its Wald interval (delta method on the coordinates).
// The interval is clipped to [lo, hi] (probabilities: [0, 1]).
template <class G>
FitParameter wald(const std::string& name, const FateHmm& h, const Coordinates& c,
                  const Eigen::MatrixXd& cov, G g, double lo = 0.0, double hi = 1.0) {
  FitParameter p;
  p.name = name;
  p.estimate = g(h);
  p.ci_low = p.ci_high = std::nan("");
  if (cov.size() == 0 && !c.entries.empty()) return p;
  const auto F = static_cast<Eigen::Index>(c.entries.size());
  Eigen::VectorXd grad(F);
  for (Eigen::Index k = 0; k < F; ++k) {
    Eigen::VectorXd d = Eigen::VectorXd::Zero(F);
    const double s = 1e-7;
    d(k) = s;
    const double up = g(moved(h, c, d));
    d(k) = -s;
    grad(k) = (up - g(moved(h, c, d))) / (2.0 * s);
  }
  const double se = F > 0 ? std::sqrt(std::max(0.0, grad.dot(cov * grad))) : 0.0;
  if (!std::isfinite(p.estimate) || !std::isfinite(se)) return p;
  p.ci_low = std::max(lo, p.estimate - 1.959963985 * se);
  p.ci_high = std::min(hi, p.estimate + 1.959963985 * se);
  p.interval = "wald";
  return p;
}

}  // namespace ncosim::models::fit_detail
