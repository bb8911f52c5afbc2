// models/fit_intervals.cc — the 95 % intervals of the fitted parameters (models/fit.h): the
// observed information of a hidden chain (numerical Hessian of the log-likelihood, or of its
// score for many coordinates), exact binomial intervals for the iid families, normal intervals of
// a mean delay, and likelihood-ratio bounds where a Wald interval says nothing (a probability the
// fit put at 0 or 1).
#include <fmt/format.h>

#include <algorithm>
#include <boost/math/special_functions/beta.hpp>
#include <cmath>

#include "models/fit.h"
#include "models/fit_internal.h"

namespace ncosim::models::fit_detail {

namespace {

constexpr double kZ95 = 1.959963985;
// Half the chi-square(1) 95 % quantile: a likelihood-ratio interval's drop in log-likelihood.
constexpr double kLrDrop = 0.5 * 3.841458821;
// Coordinates up to which the Hessian of the log-likelihood itself is differenced (O(F^2)
// likelihoods); above, the score's (O(F) E-steps).
constexpr std::size_t kLikelihoodHessianMax = 30;
// The work (packets x E-steps x K^2) above which no information matrix is computed: about a
// minute of E-steps on one core.
constexpr double kMaxInformationWork = 6e9;

// The step of each coordinate's central difference: small against both entries it moves.
Eigen::VectorXd steps(const FateHmm& h, const Coordinates& c) {
  const auto F = static_cast<Eigen::Index>(c.entries.size());
  Eigen::VectorXd step(F);
  for (Eigen::Index k = 0; k < F; ++k) {
    const auto& e = c.entries[static_cast<std::size_t>(k)];
    const Eigen::MatrixXd& mat = e.emission ? h.emission : h.transition;
    step(k) = std::min({1e-4, 0.25 * mat(e.row, e.col), 0.25 * mat(e.row, e.dependent)});
  }
  return step;
}

// The inverse of -H when H is negative definite, else empty.
Eigen::MatrixXd inverse_information(const Eigen::MatrixXd& H) {
  const Eigen::MatrixXd info = -0.5 * (H + H.transpose());
  Eigen::LLT<Eigen::MatrixXd> llt(info);
  if (llt.info() != Eigen::Success) return {};
  return llt.solve(Eigen::MatrixXd::Identity(H.rows(), H.cols()));
}

// The score in the free coordinates by Fisher's identity: d LL / d T_ij = A_ij / T_ij (expected
// transition counts), d LL / d E_im = B_im / E_im, each coordinate against its dependent entry.
Eigen::VectorXd score(const FateHmm& h, const Coordinates& c, const std::vector<int>& sym,
                      std::vector<double>& alpha, std::vector<double>& scale) {
  Eigen::MatrixXd A, B;
  e_step(h, sym, &A, &B, alpha, scale);
  Eigen::VectorXd g(static_cast<Eigen::Index>(c.entries.size()));
  for (std::size_t k = 0; k < c.entries.size(); ++k) {
    const auto& e = c.entries[k];
    const Eigen::MatrixXd& mat = e.emission ? h.emission : h.transition;
    const Eigen::MatrixXd& cnt = e.emission ? B : A;
    g(static_cast<Eigen::Index>(k)) =
        cnt(e.row, e.col) / mat(e.row, e.col) - cnt(e.row, e.dependent) / mat(e.row, e.dependent);
  }
  return g;
}

// The log-likelihood with `u` of entry (row, col) taken from entry (row, from).
double moved_loglik(const FateHmm& h, bool emission, Eigen::Index row, Eigen::Index col,
                    Eigen::Index from, double u, const std::vector<int>& sym) {
  FateHmm m = h;
  Eigen::MatrixXd& mat = emission ? m.emission : m.transition;
  mat(row, col) += u;
  mat(row, from) -= u;
  return hmm_loglik(m, sym);
}

// The largest u in (0, room] whose move keeps the log-likelihood above `floor` (bisection);
// `room` when even the whole move does.
double largest_move(const FateHmm& h, bool emission, Eigen::Index row, Eigen::Index col,
                    Eigen::Index from, double room, double floor, const std::vector<int>& sym) {
  if (moved_loglik(h, emission, row, col, from, room, sym) >= floor) return room;
  double lo = 0.0, hi = room;
  for (int i = 0; i < 50 && hi - lo > 1e-9 * std::max(hi, 1e-300); ++i) {
    const double mid = 0.5 * (lo + hi);
    (moved_loglik(h, emission, row, col, from, mid, sym) >= floor ? lo : hi) = mid;
  }
  return lo;
}

}  // namespace

Eigen::MatrixXd covariance(const FateHmm& h, const Coordinates& c, const std::vector<int>& sym) {
  const auto F = static_cast<Eigen::Index>(c.entries.size());
  const Eigen::VectorXd step = steps(h, c);
  const double f0 = hmm_loglik(h, sym);
  auto f = [&](Eigen::Index a, double sa, Eigen::Index b, double sb) {
    Eigen::VectorXd d = Eigen::VectorXd::Zero(F);
    d(a) += sa * step(a);
    if (b >= 0) d(b) += sb * step(b);
    return hmm_loglik(moved(h, c, d), sym);
  };
  Eigen::MatrixXd H(F, F);
  for (Eigen::Index a = 0; a < F; ++a) {
    H(a, a) = (f(a, 1, -1, 0) - 2.0 * f0 + f(a, -1, -1, 0)) / (step(a) * step(a));
    for (Eigen::Index b = 0; b < a; ++b) {
      H(a, b) = H(b, a) = (f(a, 1, b, 1) - f(a, 1, b, -1) - f(a, -1, b, 1) + f(a, -1, b, -1)) /
                          (4.0 * step(a) * step(b));
    }
  }
  return inverse_information(H);
}

Eigen::MatrixXd covariance_from_scores(const FateHmm& h, const Coordinates& c,
                                       const std::vector<int>& sym) {
  const auto F = static_cast<Eigen::Index>(c.entries.size());
  const Eigen::VectorXd step = steps(h, c);
  std::vector<double> alpha, scale;
  Eigen::MatrixXd H(F, F);
  for (Eigen::Index l = 0; l < F; ++l) {
    Eigen::VectorXd d = Eigen::VectorXd::Zero(F);
    d(l) = step(l);
    const Eigen::VectorXd up = score(moved(h, c, d), c, sym, alpha, scale);
    d(l) = -step(l);
    H.col(l) = (up - score(moved(h, c, d), c, sym, alpha, scale)) / (2.0 * step(l));
  }
  return inverse_information(H);
}

Eigen::MatrixXd hidden_covariance(const FateHmm& h, const Coordinates& c,
                                  const std::vector<int>& sym, std::string& why) {
  const std::size_t F = c.entries.size();
  Eigen::MatrixXd cov;
  if (F <= kLikelihoodHessianMax) {
    cov = covariance(h, c, sym);
  } else {
    const auto K = static_cast<double>(h.transition.rows());
    const double work = 2.0 * static_cast<double>(F) * static_cast<double>(sym.size()) * K * K;
    if (work > kMaxInformationWork) {
      why = fmt::format(
          "no interval: the information matrix of {} free probabilities over {} packets is too "
          "costly (fit fewer packets, or a trace with fewer delay values)",
          F, sym.size());
      return {};
    }
    cov = covariance_from_scores(h, c, sym);
  }
  if (cov.size() == 0) {
    why =
        "no interval: the observed information is singular (the trace does not identify every "
        "parameter, e.g. two hidden states alike)";
  }
  return cov;
}

FitParameter binomial(const std::string& name, double p, double n) {
  FitParameter r;
  r.name = name;
  r.estimate = p;
  r.interval = "clopper_pearson";
  if (!(n >= 1.0)) {
    r.ci_low = 0.0;
    r.ci_high = 1.0;
    return r;
  }
  const double x = std::clamp(std::round(p * n), 0.0, n);
  const double a = 1.0 - 0.95;
  r.ci_low = x > 0.0 ? boost::math::ibeta_inv(x, n - x + 1.0, a / 2.0) : 0.0;
  r.ci_high = x < n ? boost::math::ibeta_inv(x + 1.0, n - x, 1.0 - a / 2.0) : 1.0;
  return r;
}

FitParameter mean_delay(const std::string& name, const std::vector<double>& count) {
  FitParameter r;
  r.name = name;
  r.ci_low = r.ci_high = std::nan("");
  double n = 0.0, s = 0.0, ss = 0.0;
  for (std::size_t d = 0; d < count.size(); ++d) {
    const double x = static_cast<double>(d);
    n += count[d];
    s += count[d] * x;
    ss += count[d] * x * x;
  }
  if (n <= 0.0) {
    r.estimate = std::nan("");
    r.note = "no packet was delivered";
    return r;
  }
  r.estimate = s / n;
  const double var = n > 1.0 ? std::max(0.0, (ss - s * s / n) / (n - 1.0)) : 0.0;
  if (!(var > 0.0)) {
    r.note = n > 1.0 ? "every delivered packet had this delay" : "one delivered packet";
    return r;
  }
  const double se = std::sqrt(var / n);
  r.ci_low = std::max(0.0, r.estimate - kZ95 * se);
  r.ci_high = r.estimate + kZ95 * se;
  r.interval = "normal";
  return r;
}

void likelihood_ratio_interval(FitParameter& p, const FateHmm& h, bool emission, Eigen::Index row,
                               Eigen::Index col, const std::vector<int>& sym, double scale) {
  const Eigen::MatrixXd& mat = emission ? h.emission : h.transition;
  const double v = mat(row, col);
  p.ci_low = p.ci_high = std::nan("");
  p.interval.clear();
  if (!(scale > 0.0) || !std::isfinite(scale)) {
    p.note = "no interval: the parameter is not defined by the fit (nothing it conditions on)";
    return;
  }
  const double floor = hmm_loglik(h, sym) - kLrDrop;
  // The row's largest other entry gives up (or takes) the mass.
  Eigen::Index other = -1;
  for (Eigen::Index j = 0; j < mat.cols(); ++j) {
    if (j != col && (other < 0 || mat(row, j) > mat(row, other))) other = j;
  }
  if (other < 0) {
    p.note = "no interval: a single outcome";
    return;
  }
  if (v <= 0.5) {  // at 0: how far up the data allow it
    const double up = largest_move(h, emission, row, col, other, mat(row, other), floor, sym);
    p.ci_low = 0.0;
    p.ci_high = std::min(1.0, (v + up) * scale);
  } else {  // at 1: how far down
    const double down = largest_move(h, emission, row, other, col, v, floor, sym);
    p.ci_low = std::max(0.0, (v - down) * scale);
    p.ci_high = std::min(1.0, v * scale);
  }
  p.interval = "likelihood_ratio";
  p.note = "at the edge of its range: a likelihood-ratio bound, the other parameters held";
}

}  // namespace ncosim::models::fit_detail
