// tests/estimators/kalman_update_test.cc — the Kalman kernel against the textbook gain form
// (K = P C' S^-1, x + K r, P - K S K', Eigen's LLT), for state sizes on every code path (the
// fixed sizes 1..8, the run-time loops up to 16, Eigen's products beyond) and row subsets.
#include "estimators/kalman_update.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

namespace ncosim::est {
namespace {

Eigen::MatrixXd random_spd(Eigen::Index n, std::mt19937_64& rng) {
  std::normal_distribution<double> g;
  Eigen::MatrixXd M(n, n);
  for (Eigen::Index i = 0; i < M.size(); ++i) M.data()[i] = g(rng);
  return M * M.transpose() / static_cast<double>(n) + 0.1 * Eigen::MatrixXd::Identity(n, n);
}

Eigen::MatrixXd random_matrix(Eigen::Index r, Eigen::Index c, std::mt19937_64& rng) {
  std::normal_distribution<double> g;
  Eigen::MatrixXd M(r, c);
  for (Eigen::Index i = 0; i < M.size(); ++i) M.data()[i] = g(rng);
  return M;
}

double rel(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return (a - b).norm() / (1.0 + b.norm());
}

TEST(KalmanUpdate, PredictAndUpdateMatchTheTextbookFormOnEverySizeAndRowSubset) {
  std::mt19937_64 rng(16);
  for (Eigen::Index n : {1, 2, 3, 4, 5, 6, 7, 8, 9, 12, 16, 17, 24}) {
    const Eigen::Index m_all = std::min<Eigen::Index>(n + 1, 5);
    const Eigen::MatrixXd A = random_matrix(n, n, rng) / std::sqrt(static_cast<double>(n));
    const Eigen::MatrixXd Q = random_spd(n, rng), R = random_spd(m_all, rng);
    const Eigen::MatrixXd C = random_matrix(m_all, n, rng);
    Eigen::VectorXd x = random_matrix(n, 1, rng), xr = x;
    Eigen::MatrixXd P = random_spd(n, rng), Pr = P;
    kalman::Workspace ws(n, m_all);
    for (int step = 0; step < 6; ++step) {
      SCOPED_TRACE(testing::Message() << "n = " << n << ", step " << step);
      kalman::predict_state(A, x, ws);
      kalman::predict_covariance(A, Q, P, ws);
      xr = A * xr;
      Pr = A * Pr * A.transpose() + Q;
      EXPECT_LT(rel(x, xr), 1e-12);
      EXPECT_LT(rel(P, Pr), 1e-12);
      EXPECT_EQ(P, P.transpose());  // exactly symmetric
      // Rows: a different subset each step (never empty).
      std::vector<Eigen::Index> rows;
      for (Eigen::Index r = 0; r < m_all; ++r) {
        if (((step + 1) >> (r % 3)) & 1 || r == step % m_all) rows.push_back(r);
      }
      const auto m = static_cast<Eigen::Index>(rows.size());
      const Eigen::VectorXd y = random_matrix(m_all, 1, rng);
      kalman::select(C, R, y, rows.data(), m, ws);
      ASSERT_EQ(kalman::factor(x, P, ws), kalman::Factor::kOk);
      const double loglik = ws.log_likelihood();
      kalman::apply(x, P, ws);
      Eigen::MatrixXd Cs(m, n), Rs(m, m);
      Eigen::VectorXd ys(m);
      for (Eigen::Index a = 0; a < m; ++a) {
        Cs.row(a) = C.row(rows[a]);
        ys(a) = y(rows[a]);
        for (Eigen::Index b = 0; b < m; ++b) Rs(a, b) = R(rows[a], rows[b]);
      }
      const Eigen::MatrixXd S = Cs * Pr * Cs.transpose() + Rs;
      const Eigen::LLT<Eigen::MatrixXd> llt(S);
      const Eigen::MatrixXd K = Pr * Cs.transpose() * llt.solve(Eigen::MatrixXd::Identity(m, m));
      const Eigen::VectorXd r = ys - Cs * xr;
      const double loglik_ref = -0.5 * r.dot(llt.solve(r)) - 0.5 * std::log(S.determinant()) -
                                0.5 * static_cast<double>(m) * std::log(2.0 * std::numbers::pi);
      xr += K * r;
      Pr -= K * S * K.transpose();
      Pr = 0.5 * (Pr + Pr.transpose()).eval();
      EXPECT_LT(rel(x, xr), 1e-10);
      EXPECT_LT(rel(P, Pr), 1e-10);
      EXPECT_EQ(P, P.transpose());
      EXPECT_NEAR(loglik, loglik_ref, 1e-9 * (1.0 + std::abs(loglik_ref)));
      x = xr;  // keep the two in step: compare one step at a time
      P = Pr;
    }
  }
}

TEST(KalmanUpdate, SemidefiniteInnovationFallsBackToThePseudoInverse) {
  // P = 0 and R = 0: S = 0, no Cholesky; the minimum-variance gain P C' S^+ is 0 here.
  const Eigen::Index n = 3;
  Eigen::VectorXd x = Eigen::VectorXd::Constant(n, 1.0);
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(n, n);
  const Eigen::MatrixXd C = Eigen::MatrixXd::Identity(2, n), R = Eigen::MatrixXd::Zero(2, 2);
  const Eigen::VectorXd y = Eigen::VectorXd::Constant(2, 5.0);
  const Eigen::Index rows[] = {0, 1};
  kalman::Workspace ws(n, 2);
  kalman::select(C, R, y, rows, 2, ws);
  ASSERT_EQ(kalman::factor(x, P, ws), kalman::Factor::kNotPositiveDefinite);
  kalman::apply_pseudo_inverse(x, P, ws);
  EXPECT_EQ(x, Eigen::VectorXd::Constant(n, 1.0));
  EXPECT_EQ(P, Eigen::MatrixXd::Zero(n, n));
  // The same rows with P > 0: S = C P C' = I is positive definite again.
  P = Eigen::MatrixXd::Identity(n, n);
  kalman::select(C, R, y, rows, 2, ws);
  EXPECT_EQ(kalman::factor(x, P, ws), kalman::Factor::kOk);  // S = C P C' = I
}

TEST(KalmanUpdate, NonFiniteMeasurementIsReportedAndChangesNothing) {
  const Eigen::Index n = 2;
  Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
  Eigen::MatrixXd P = Eigen::MatrixXd::Identity(n, n);
  const Eigen::MatrixXd C = Eigen::MatrixXd::Identity(1, n), R = Eigen::MatrixXd::Identity(1, 1);
  const Eigen::VectorXd y = Eigen::VectorXd::Constant(1, std::nan(""));
  const Eigen::Index rows[] = {0};
  kalman::Workspace ws(n, 1);
  kalman::select(C, R, y, rows, 1, ws);
  EXPECT_EQ(kalman::factor(x, P, ws), kalman::Factor::kNonFinite);
  EXPECT_EQ(x, Eigen::VectorXd::Zero(n));
  EXPECT_EQ(P, Eigen::MatrixXd::Identity(n, n));
}

}  // namespace
}  // namespace ncosim::est
