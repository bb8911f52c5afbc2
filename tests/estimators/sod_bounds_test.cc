// tests/estimators/sod_bounds_test.cc — the send-on-delta paper's probability and virtual-noise
// bounds (29), (30), (33), (34) against Monte Carlo of their assumptions, and (28) on the
// paper's example 5.1 (checked independently for this project: r = [0.511 0.413] for ||w||inf =
// [0.8 0.7]).
#include "estimators/design/sod_bounds.h"

#include <gtest/gtest.h>

#include <boost/random/mersenne_twister.hpp>
#include <boost/random/normal_distribution.hpp>
#include <boost/random/uniform_real_distribution.hpp>
#include <cmath>

namespace ncosim::est::sod {
namespace {

TEST(SodBounds, UniformRangeOfExample51) {
  Eigen::MatrixXd C(2, 3), B(3, 2);
  C << 0.519, -0.233, 0.095, 0.569, 0, 0;
  B << -0.229, 0.023, 0.231, 0.211, -0.186, 0.245;
  const Eigen::VectorXd r =
      uniform_range(C, B, Eigen::Vector2d(0.8, 0.7), Eigen::Vector2d(0.15, 0.15));
  EXPECT_NEAR(r(0), 0.5113, 5e-4);
  EXPECT_NEAR(r(1), 0.4133, 5e-4);
}

// Monte Carlo of the assumption: d = y1 - y0 with y0, y1 independent (uniform on a range of
// width r, or d normal with std sigma); beta = P(|d| >= Delta), sigma^2 = E[d^2 1{|d| < Delta}].
// N = 1e6: the standard error of beta is <= 5e-4 and of sigma^2 <= Delta^2 / 1e3; bounds at 5 SE.
TEST(SodBounds, UniformAndGaussianMatchMonteCarlo) {
  boost::random::mt19937_64 rng(42);
  const int n = 1'000'000;
  for (const double delta : {0.1, 0.4, 0.7}) {
    const double r = 0.9;
    boost::random::uniform_real_distribution<double> u(0.0, r);
    double sent = 0, sse = 0;
    for (int i = 0; i < n; ++i) {
      const double d = u(rng) - u(rng);
      if (std::abs(d) >= delta)
        ++sent;
      else
        sse += d * d;
    }
    EXPECT_NEAR(sent / n, uniform_beta(delta, r), 2.5e-3) << delta;
    EXPECT_NEAR(sse / n, uniform_sigma2(delta, r), 5 * delta * delta / 1e3) << delta;
    EXPECT_NEAR(uniform_delta_for_beta(uniform_beta(delta, r), r), delta, 1e-12);

    const double sigma = 0.3;
    boost::random::normal_distribution<double> g(0.0, sigma);
    sent = sse = 0;
    for (int i = 0; i < n; ++i) {
      const double d = g(rng);
      if (std::abs(d) >= delta)
        ++sent;
      else
        sse += d * d;
    }
    EXPECT_NEAR(sent / n, gaussian_beta(delta, sigma), 2.5e-3) << delta;
    EXPECT_NEAR(sse / n, gaussian_sigma2(delta, sigma), 5 * delta * delta / 1e3) << delta;
    EXPECT_NEAR(gaussian_delta_for_beta(gaussian_beta(delta, sigma), sigma), delta, 1e-9);
  }
  // Beyond the range: never sends in the least excited case; sigma^2 continuous at Delta = r.
  EXPECT_EQ(uniform_beta(1.0, 0.9), 0.0);
  EXPECT_NEAR(uniform_sigma2(0.9, 0.9), 0.81 / 6.0, 1e-15);
  EXPECT_NEAR(uniform_sigma2(0.9 - 1e-9, 0.9), 0.81 / 6.0, 1e-8);
}

TEST(SodBounds, Costs) {
  EXPECT_NEAR(cost_deterministic(Eigen::Vector2d(0.5, 0.25), Eigen::Vector2d(0.9, 0.75)), 1.8 + 3.0,
              1e-15);
  EXPECT_NEAR(cost_stochastic(Eigen::Vector2d(0.5, 0.2)), 1.0 - 0.5 * 0.8, 1e-15);
}

}  // namespace
}  // namespace ncosim::est::sod
