// tests/models/transfer_function_test.cc — transfer function with dead time, ZOH: the sampled
// step response equals the continuous one, including a fractional dead time.
#include <gtest/gtest.h>

#include <cmath>

#include "models/controller.h"
#include "models/plant.h"

namespace ncosim::models {
namespace {

// Step response of the discrete model y[k] = C x[k], x[k+1] = A x[k] + Bu * 1.
std::vector<double> step(const LinearPlant& p, int periods) {
  Eigen::VectorXd x = Eigen::VectorXd::Zero(p.n());
  std::vector<double> y;
  for (int k = 0; k < periods; ++k) {
    y.push_back((p.C_out * x)(0));
    x = p.A * x + p.Bu.col(0);
  }
  return y;
}

TEST(TransferFunction, FirstOrderWithFractionalDeadTime) {
  // G(s) = 2 e^{-0.25 s} / (0.5 s + 1), T = 0.1: y(t) = 2 (1 - e^{-(t - 0.25)/0.5}) for t >= 0.25.
  const LinearPlant p = discretise_transfer_function({2.0}, {0.5, 1.0}, 0.25, 0.1);
  EXPECT_EQ(p.n(), 1 + 3);  // plant + u[k-1], u[k-2], u[k-3] (dead time 2.5 periods)
  const auto y = step(p, 30);
  for (int k = 0; k < 30; ++k) {
    const double t = 0.1 * k;
    const double expected = t < 0.25 ? 0.0 : 2.0 * (1.0 - std::exp(-(t - 0.25) / 0.5));
    EXPECT_NEAR(y[static_cast<std::size_t>(k)], expected, 1e-12) << k;
  }
}

TEST(TransferFunction, SecondOrderMotorOfExample52) {
  // G(s) = 5.1 e^{-0.01 s} / ((1 + 0.033 s)(1 + 0.0032 s)) at T = 5 ms: dead time = 2 periods.
  const double a = 0.033, b = 0.0032;
  const LinearPlant p = discretise_transfer_function({5.1}, {a * b, a + b, 1.0}, 0.01, 0.005);
  EXPECT_EQ(p.n(), 2 + 2);
  const auto y = step(p, 200);
  for (int k = 0; k < 200; ++k) {
    const double t = 0.005 * k - 0.01;
    // Step response of 5.1 / ((1 + a s)(1 + b s)): 5.1 (1 - (a e^{-t/a} - b e^{-t/b}) / (a - b)).
    const double expected =
        t <= 0 ? 0.0 : 5.1 * (1.0 - (a * std::exp(-t / a) - b * std::exp(-t / b)) / (a - b));
    EXPECT_NEAR(y[static_cast<std::size_t>(k)], expected, 1e-9 * 5.1) << k;
  }
  EXPECT_NEAR(y.back(), 5.1, 1e-6);  // DC gain
  // The input disturbance enters undelayed: Bw is the ZOH input matrix of the plant states.
  EXPECT_EQ(p.Bw.bottomRows(2).norm(), 0.0);
  EXPECT_GT(p.Bw.topRows(2).norm(), 0.0);
}

TEST(TransferFunction, NoDeadTimeIsPlainZoh) {
  const LinearPlant p = discretise_transfer_function({1.0}, {1.0, 1.0}, 0.0, 0.2);
  ASSERT_EQ(p.n(), 1);
  EXPECT_NEAR(p.A(0, 0), std::exp(-0.2), 1e-15);
  EXPECT_NEAR(p.Bu(0, 0), 1.0 - std::exp(-0.2), 1e-15);
}

TEST(Reference, SquareWaveStartsLow) {
  const Reference r{40.0, 50.0, 1.0};
  EXPECT_EQ(r.at(0.0), 40.0);
  EXPECT_EQ(r.at(0.495), 40.0);
  EXPECT_EQ(r.at(0.5), 50.0);  // switches at half a period (robust to t = k T rounding)
  EXPECT_EQ(r.at(0.005 * 100), 50.0);
  EXPECT_EQ(r.at(0.999), 50.0);
  EXPECT_EQ(r.at(1.0), 40.0);
  const Reference c{3.0, 3.0, 0.0};
  EXPECT_EQ(c.at(123.0), 3.0);
}

}  // namespace
}  // namespace ncosim::models
