// tests/models/plant_test.cc — exact discretisation of lti_continuous (ZOH and Van Loan).
#include "models/plant.h"

#include <gtest/gtest.h>

#include <cmath>

namespace ncosim::models {
namespace {

TEST(Discretise, ScalarSystemMatchesClosedForm) {
  // dx = (a x + b u) dt + dβ, E dβ² = q dt, period T:
  // A = e^{aT}, Bu = b (e^{aT} - 1)/a, W = q (e^{2aT} - 1)/(2a).
  const double a = -0.7, b = 2.0, q = 0.3, T = 0.25;
  const LinearPlant p =
      discretise(Eigen::MatrixXd::Constant(1, 1, a), Eigen::MatrixXd::Constant(1, 1, b),
                 Eigen::MatrixXd::Identity(1, 1), Eigen::MatrixXd::Constant(1, 1, q), T);
  EXPECT_NEAR(p.A(0, 0), std::exp(a * T), 1e-15);
  EXPECT_NEAR(p.Bu(0, 0), b * (std::exp(a * T) - 1) / a, 1e-15);
  EXPECT_NEAR(p.W(0, 0), q * (std::exp(2 * a * T) - 1) / (2 * a), 1e-15);
}

TEST(Discretise, DoubleIntegratorMatchesClosedForm) {
  // x = (position, velocity), acceleration u plus white noise of intensity q:
  // A = [[1, T], [0, 1]], Bu = [T²/2; T], W = q [[T³/3, T²/2], [T²/2, T]].
  const double q = 0.5, T = 0.1;
  Eigen::MatrixXd Ac(2, 2), Bc(2, 1), Gc(2, 1);
  Ac << 0, 1, 0, 0;
  Bc << 0, 1;
  Gc << 0, 1;
  const LinearPlant p = discretise(Ac, Bc, Gc, Eigen::MatrixXd::Constant(1, 1, q), T);
  Eigen::MatrixXd A(2, 2), B(2, 1), W(2, 2);
  A << 1, T, 0, 1;
  B << T * T / 2, T;
  W << q * T * T * T / 3, q * T * T / 2, q * T * T / 2, q * T;
  EXPECT_LT((p.A - A).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LT((p.Bu - B).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LT((p.W - W).cwiseAbs().maxCoeff(), 1e-16) << p.W;
  EXPECT_EQ(p.Bw.rows(), 2);
  EXPECT_EQ(p.Bw.cols(), 2);
}

TEST(PsdSqrt, SquaresBackAndClipsRoundingNegatives) {
  Eigen::MatrixXd M(2, 2);
  M << 0.2632, -0.0027, -0.0027, 0.2466;
  const Eigen::MatrixXd S = psd_sqrt(M);
  EXPECT_LT((S * S.transpose() - M).cwiseAbs().maxCoeff(), 1e-15);
  Eigen::MatrixXd singular(2, 2);
  singular << 1, 1, 1, 1;
  const Eigen::MatrixXd S2 = psd_sqrt(singular);
  EXPECT_LT((S2 * S2.transpose() - singular).cwiseAbs().maxCoeff(), 1e-14);
}

}  // namespace
}  // namespace ncosim::models
