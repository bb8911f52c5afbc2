// estimators/design/sod_bounds.cc
#include "estimators/design/sod_bounds.h"

#include <algorithm>
#include <boost/math/special_functions/erf.hpp>
#include <cmath>
#include <limits>
#include <numbers>

namespace ncosim::est::sod {

Eigen::VectorXd uniform_range(const Eigen::MatrixXd& C, const Eigen::MatrixXd& Bw,
                              const Eigen::VectorXd& w_inf, const Eigen::VectorXd& v_inf) {
  Eigen::VectorXd r(C.rows());
  for (Eigen::Index i = 0; i < C.rows(); ++i) {
    double s = 0.0;
    for (Eigen::Index j = 0; j < Bw.cols(); ++j) {
      double cb = 0.0;
      for (Eigen::Index k = 0; k < C.cols(); ++k) cb += std::abs(C(i, k) * Bw(k, j));
      s += cb * w_inf(j);
    }
    r(i) = s + 2.0 * v_inf(i);
  }
  return r;
}

double uniform_beta(double delta, double r) {
  if (delta >= r) return 0.0;
  const double q = (r - delta) / r;
  return q * q;
}

double uniform_sigma2(double delta, double r) {
  if (delta >= r) return r * r / 6.0;
  return 2.0 * delta * delta * delta / (r * r) * (r / 3.0 - delta / 4.0);
}

double uniform_delta_for_beta(double beta, double r) {
  return r * (1.0 - std::sqrt(std::clamp(beta, 0.0, 1.0)));
}

double gaussian_beta(double delta, double sigma) {
  return 1.0 - std::erf(delta / (std::sqrt(2.0) * sigma));
}

double gaussian_sigma2(double delta, double sigma) {
  const double e = std::erf(delta / (std::sqrt(2.0) * sigma));
  return sigma * sigma * e - std::sqrt(2.0 / std::numbers::pi) * delta * sigma *
                                 std::exp(-delta * delta / (2.0 * sigma * sigma));
}

double gaussian_delta_for_beta(double beta, double sigma) {
  const double b = std::clamp(beta, 0.0, 1.0);
  if (b <= 0.0) return std::numeric_limits<double>::infinity();
  if (b >= 1.0) return 0.0;
  return std::sqrt(2.0) * sigma * boost::math::erf_inv(1.0 - b);
}

double cost_deterministic(const Eigen::VectorXd& delta, const Eigen::VectorXd& g) {
  double j = 0.0;
  for (Eigen::Index i = 0; i < delta.size(); ++i) j += g(i) / delta(i);
  return j;
}

double cost_stochastic(const Eigen::VectorXd& beta) {
  double p0 = 1.0;
  for (Eigen::Index i = 0; i < beta.size(); ++i) p0 *= 1.0 - beta(i);
  return 1.0 - p0;
}

}  // namespace ncosim::est::sod
