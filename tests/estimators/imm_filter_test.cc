// tests/estimators/imm_filter_test.cc — the IMM numerical core against filterpy and known cases.
#include "estimators/imm_filter.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

namespace ncosim::est {
namespace {

// A CSV file with a header row and numeric cells (the peer files have CRLF line ends).
struct Csv {
  std::map<std::string, std::size_t> column;
  std::vector<std::vector<double>> rows;
  double at(std::size_t row, const std::string& name) const {
    return rows[row].at(column.at(name));
  }
};

Csv read_csv(const std::string& path) {
  Csv csv;
  std::ifstream in(path);
  std::string line;
  const auto next_line = [&in, &line] {
    if (!std::getline(in, line)) return false;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  };
  if (!next_line()) return csv;
  std::stringstream header(line);
  for (std::string cell; std::getline(header, cell, ',');) csv.column[cell] = csv.column.size();
  while (next_line()) {
    std::stringstream ss(line);
    std::vector<double> v;
    for (std::string cell; std::getline(ss, cell, ',');) v.push_back(std::stod(cell));
    csv.rows.push_back(std::move(v));
  }
  return csv;
}

// The peer system of tests/data/peers/README.md: constant velocity, F = [[1, 1], [0, 1]],
// Q = G G' q with G = [0.5; 1], H = [1 0], R = 1, no input.
ImmMode peer_mode(double q) {
  ImmMode mode;
  mode.F.resize(2, 2);
  mode.F << 1, 1, 0, 1;
  mode.B = Eigen::MatrixXd::Zero(2, 0);
  Eigen::Vector2d G(0.5, 1.0);
  mode.Q = G * G.transpose() * q;
  mode.H.resize(1, 2);
  mode.H << 1, 0;
  mode.R = Eigen::MatrixXd::Identity(1, 1);
  return mode;
}

Eigen::MatrixXd peer_transition() {
  Eigen::MatrixXd M(2, 2);
  M << 0.95, 0.05, 0.10, 0.90;
  return M;
}

ImmFilter peer_filter(double q0, double q1) {
  return ImmFilter({peer_mode(q0), peer_mode(q1)}, peer_transition(), Eigen::VectorXd::Zero(2),
                   10.0 * Eigen::MatrixXd::Identity(2, 2), Eigen::Vector2d(0.5, 0.5));
}

double rel_dev(double got, double want) {
  return std::abs(got - want) / std::max(1.0, std::abs(want));
}

// filterpy 1.4.5 IMMEstimator (tests/data/peers/README.md): row k is the state after
// predict + update(z(k)). Both sides compute the same textbook recursion, so they should
// agree to rounding (the README's own cross-check is about 1e-13); 1e-9 leaves room for the
// different but equivalent forms (Joseph vs U'U covariance update, logpdf via eigh vs
// Cholesky). x_prior is not compared: filterpy combines it with the previous mu, not cbar.
TEST(ImmFilter, MatchesFilterpyTwoModeTrackerStepByStep) {
  const Csv inputs = read_csv(NCOSIM_SOURCE_DIR "/tests/data/peers/imm_filterpy_inputs.csv");
  const Csv ref = read_csv(NCOSIM_SOURCE_DIR "/tests/data/peers/imm_filterpy_output.csv");
  ASSERT_EQ(inputs.rows.size(), 200U) << "peer inputs not found or truncated";
  ASSERT_EQ(ref.rows.size(), 200U) << "peer outputs not found or truncated";
  ImmFilter imm = peer_filter(0.01, 1.0);

  const std::vector<std::string> names = {"mu0",    "mu1",    "x0",     "x1",     "P00",   "P01",
                                          "P11",    "lik0",   "lik1",   "cbar0",  "cbar1", "f0_x0",
                                          "f0_x1",  "f0_P00", "f0_P01", "f0_P11", "f1_x0", "f1_x1",
                                          "f1_P00", "f1_P01", "f1_P11"};
  std::map<std::string, double> worst;
  std::map<std::string, std::size_t> worst_step;
  for (std::size_t k = 0; k < inputs.rows.size(); ++k) {
    ASSERT_EQ(inputs.at(k, "k"), static_cast<double>(k));
    ASSERT_EQ(ref.at(k, "k"), static_cast<double>(k));
    imm.predict();
    imm.update(Eigen::Matrix<double, 1, 1>(inputs.at(k, "z")));
    ASSERT_EQ(imm.status(), ImmStatus::kOk) << "step " << k;
    std::map<std::string, double> got = {
        {"mu0", imm.mu()(0)},     {"mu1", imm.mu()(1)},        {"x0", imm.x()(0)},
        {"x1", imm.x()(1)},       {"P00", imm.P()(0, 0)},      {"P01", imm.P()(0, 1)},
        {"P11", imm.P()(1, 1)},   {"lik0", imm.likelihood(0)}, {"lik1", imm.likelihood(1)},
        {"cbar0", imm.cbar()(0)}, {"cbar1", imm.cbar()(1)}};
    for (int j = 0; j < 2; ++j) {
      const std::string f = "f" + std::to_string(j) + "_";
      got[f + "x0"] = imm.mode_x(j)(0);
      got[f + "x1"] = imm.mode_x(j)(1);
      got[f + "P00"] = imm.mode_P(j)(0, 0);
      got[f + "P01"] = imm.mode_P(j)(0, 1);
      got[f + "P11"] = imm.mode_P(j)(1, 1);
    }
    for (const std::string& name : names) {
      double dev = rel_dev(got.at(name), ref.at(k, name));
      if (std::isnan(dev)) dev = std::numeric_limits<double>::infinity();
      if (dev > worst[name]) {
        worst[name] = dev;
        worst_step[name] = k;
      }
    }
  }
  for (const std::string& name : names) {
    std::printf("  %-7s worst relative deviation %.3e at step %zu\n", name.c_str(), worst[name],
                worst_step[name]);
    EXPECT_LE(worst[name], 1e-9) << name << " at step " << worst_step[name];
  }
}

// A missing measurement carries no information: every likelihood is 1, so
// mu_j = cbar_j * 1 / sum_i cbar_i * 1 = cbar_j, and each mode posterior is its prior. After
// 10 steps along a made-up track, one more predict gives the priors; skip_update() and an all-zero
// row mask must both leave them bit for bit.
TEST(ImmFilter, MissingMeasurementGivesMuEqualCbarAndPosteriorsEqualPriors) {
  ImmFilter imm = peer_filter(0.01, 1.0);
  const double z[10] = {0.37, 0.61, 1.9, 2.2, 3.9, 6.1, 8.8, 12.0, 15.5, 19.7};
  for (double zk : z) {
    imm.predict();
    imm.update(Eigen::Matrix<double, 1, 1>(zk));
  }
  const Eigen::Vector2d mu_before = imm.mu();
  imm.predict();
  const Eigen::Vector2d cbar = imm.cbar();
  // cbar = M' mu by hand.
  EXPECT_NEAR(cbar(0), 0.95 * mu_before(0) + 0.10 * mu_before(1), 1e-15);
  EXPECT_NEAR(cbar(1), 0.05 * mu_before(0) + 0.90 * mu_before(1), 1e-15);
  const std::vector<Eigen::VectorXd> x_prior = {imm.mode_x(0), imm.mode_x(1)};
  const std::vector<Eigen::MatrixXd> P_prior = {imm.mode_P(0), imm.mode_P(1)};
  const Eigen::VectorXd x_comb_prior = imm.x();

  for (int variant = 0; variant < 2; ++variant) {
    ImmFilter copy = imm;
    if (variant == 0) {
      copy.skip_update();
    } else {
      copy.update(Eigen::Matrix<double, 1, 1>(1e6), Eigen::Matrix<double, 1, 1>(0.0));
    }
    SCOPED_TRACE(variant == 0 ? "skip_update()" : "all-zero row mask");
    EXPECT_FALSE(copy.last_update_applied());
    EXPECT_EQ(copy.status(), ImmStatus::kOk);
    EXPECT_EQ(copy.mu(), cbar) << "mu = " << copy.mu().transpose();
    for (int j = 0; j < 2; ++j) {
      EXPECT_EQ(copy.likelihood(j), 1.0);
      EXPECT_EQ(copy.mode_x(j), x_prior[static_cast<std::size_t>(j)]);
      EXPECT_EQ(copy.mode_P(j), P_prior[static_cast<std::size_t>(j)]);
    }
    EXPECT_EQ(copy.x(), x_comb_prior);
  }
}

// Two identical modes have identical likelihoods, so mu_j = cbar_j Lambda / (Lambda sum_i
// cbar_i) = cbar_j at every step (cbar follows M' mu towards the stationary [2/3, 1/3]), and
// mixing identical estimates changes nothing: the combined estimate is one Kalman filter of
// that model. Measurements: the 200 peer z's. Tolerance 1e-12 (rounding in the mixing sums).
TEST(ImmFilter, IdenticalModesGiveMuEqualCbarAndMatchSingleKalmanFilter) {
  const Csv inputs = read_csv(NCOSIM_SOURCE_DIR "/tests/data/peers/imm_filterpy_inputs.csv");
  ASSERT_EQ(inputs.rows.size(), 200U) << "peer inputs not found or truncated";
  const double q = 0.1;
  ImmFilter imm = peer_filter(q, q);
  const ImmMode kf = peer_mode(q);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(2);
  Eigen::MatrixXd P = 10.0 * Eigen::MatrixXd::Identity(2, 2);
  double worst_mu = 0.0, worst_x = 0.0, worst_P = 0.0;
  for (std::size_t k = 0; k < inputs.rows.size(); ++k) {
    const double z = inputs.at(k, "z");
    imm.predict();
    imm.update(Eigen::Matrix<double, 1, 1>(z));
    x = kf.F * x;
    P = kf.F * P * kf.F.transpose() + kf.Q;
    const Eigen::MatrixXd S = kf.H * P * kf.H.transpose() + kf.R;
    const Eigen::MatrixXd K = P * kf.H.transpose() * S.inverse();
    x += K * (Eigen::Matrix<double, 1, 1>(z) - kf.H * x);
    P -= K * S * K.transpose();
    worst_mu = std::max(worst_mu, (imm.mu() - imm.cbar()).cwiseAbs().maxCoeff());
    worst_x = std::max(worst_x, (imm.x() - x).cwiseAbs().maxCoeff() / std::max(1.0, x.norm()));
    worst_P = std::max(worst_P, (imm.P() - P).cwiseAbs().maxCoeff() / std::max(1.0, P.norm()));
  }
  std::printf("  |mu - cbar| %.3e, x rel %.3e, P rel %.3e; final cbar %.15f %.15f\n", worst_mu,
              worst_x, worst_P, imm.cbar()(0), imm.cbar()(1));
  EXPECT_LE(worst_mu, 1e-12);
  EXPECT_LE(worst_x, 1e-12);
  EXPECT_LE(worst_P, 1e-12);
  EXPECT_NEAR(imm.cbar()(0), 2.0 / 3.0, 1e-12);  // stationary law of M after 200 steps
}

// Scalar x, two modes that differ only in the input gain: x(k+1) = x + b_j u with b = (0, 1e-3),
// Q = 0, P0 = 0, R = 1, M = 0.5 everywhere, mu0 = (0.5, 0.5). One step with u = 1 and
// z = 1000: priors x_0 = 0, x_1 = 1e-3, S_j = 1, innovations 1000 and 999.999 (1e3 sigma), so
// log Lambda_j is about -5e5 and both likelihoods underflow to exactly 0 (naive mu = 0/0).
// In the log domain log(mu_1 / mu_0) = 0.5 (1000^2 - 999.999^2) = 1 - 5e-7, so
// mu_1 = 1 / (1 + exp(-(1 - 5e-7))) = 0.731058...
TEST(ImmFilter, UnderflowingLikelihoodsStillGiveFiniteNormalisedMu) {
  ImmMode a;
  a.F = Eigen::MatrixXd::Identity(1, 1);
  a.B = Eigen::MatrixXd::Zero(1, 1);
  a.Q = Eigen::MatrixXd::Zero(1, 1);
  a.H = Eigen::MatrixXd::Identity(1, 1);
  a.R = Eigen::MatrixXd::Identity(1, 1);
  ImmMode b = a;
  b.B(0, 0) = 1e-3;
  ImmFilter imm({a, b}, Eigen::MatrixXd::Constant(2, 2, 0.5), Eigen::VectorXd::Zero(1),
                Eigen::MatrixXd::Zero(1, 1), Eigen::Vector2d(0.5, 0.5));
  imm.predict(Eigen::VectorXd::Ones(1));
  imm.update(Eigen::VectorXd::Constant(1, 1000.0));
  ASSERT_EQ(imm.status(), ImmStatus::kOk);
  EXPECT_TRUE(imm.last_update_applied());
  EXPECT_EQ(imm.likelihood(0), 0.0);  // the case is real: both underflow
  EXPECT_EQ(imm.likelihood(1), 0.0);
  const double log_2pi = std::log(2.0 * std::numbers::pi);
  EXPECT_NEAR(imm.log_likelihood(0), -0.5 * 1000.0 * 1000.0 - 0.5 * log_2pi, 1e-9);
  EXPECT_NEAR(imm.log_likelihood(1), -0.5 * 999.999 * 999.999 - 0.5 * log_2pi, 1e-9);
  const double mu1 = 1.0 / (1.0 + std::exp(-(1.0 - 5e-7)));
  EXPECT_TRUE(imm.mu().allFinite() && imm.x().allFinite() && imm.P().allFinite());
  EXPECT_NEAR(imm.mu().sum(), 1.0, 1e-15);
  EXPECT_NEAR(imm.mu()(1), mu1, 1e-9) << "mu = " << imm.mu().transpose();
  EXPECT_EQ(imm.most_probable_mode(), 1);

  // Wildly mismatched peer modes (q = 1e-6 and 1e4): a 1e3-sigma jump in z drives the
  // quiet mode's likelihood to 0 while mu stays a distribution.
  ImmFilter wild = peer_filter(1e-6, 1e4);
  for (int k = 0; k < 20; ++k) {
    wild.predict();
    wild.update(Eigen::Matrix<double, 1, 1>(0.0));
  }
  wild.predict();
  const double sigma0 = std::sqrt(wild.mode_P(0)(0, 0) + 1.0);
  wild.update(Eigen::Matrix<double, 1, 1>(1e3 * sigma0));
  std::printf("  wild: log lik %.4g %.4g, mu %.3e %.17g\n", wild.log_likelihood(0),
              wild.log_likelihood(1), wild.mu()(0), wild.mu()(1));
  ASSERT_EQ(wild.status(), ImmStatus::kOk);
  EXPECT_EQ(wild.likelihood(0), 0.0);
  EXPECT_TRUE(wild.mu().allFinite() && wild.x().allFinite() && wild.P().allFinite());
  EXPECT_NEAR(wild.mu().sum(), 1.0, 1e-15);
  EXPECT_EQ(wild.most_probable_mode(), 1);
}

// A row mask selects the marginal of the measurement: rows {0} of z = [x0; x1] + v with a
// correlated R must give the same filter as H = [1 0], R = R(0, 0) (every third step no row
// arrives: the all-zero mask must match skip_update()). Same operations on the same numbers,
// so equal to rounding (1e-14).
TEST(ImmFilter, RowMaskUpdateEqualsUpdateWithSelectedRows) {
  const auto two_rows = [](double q) {
    ImmMode mode = peer_mode(q);
    mode.H = Eigen::MatrixXd::Identity(2, 2);
    mode.R.resize(2, 2);
    mode.R << 1.0, 0.3, 0.3, 0.5;
    return mode;
  };
  ImmFilter full({two_rows(0.01), two_rows(1.0)}, peer_transition(), Eigen::VectorXd::Zero(2),
                 10.0 * Eigen::MatrixXd::Identity(2, 2), Eigen::Vector2d(0.5, 0.5));
  ImmFilter one = peer_filter(0.01, 1.0);
  double worst = 0.0;
  for (int k = 0; k < 30; ++k) {
    const Eigen::Vector2d z(0.03 * k * k + std::sin(k), 99.0);  // row 1 must be ignored
    full.predict();
    one.predict();
    if (k % 3 == 2) {
      full.update(z, Eigen::Vector2d(0.0, 0.0));
      one.skip_update();
    } else {
      full.update(z, Eigen::Vector2d(1.0, 0.0));
      one.update(z.head(1));
    }
    EXPECT_EQ(full.last_update_applied(), one.last_update_applied());
    worst = std::max({worst, (full.mu() - one.mu()).cwiseAbs().maxCoeff(),
                      (full.x() - one.x()).cwiseAbs().maxCoeff(),
                      (full.P() - one.P()).cwiseAbs().maxCoeff()});
  }
  std::printf("  masked vs one-row filter: worst deviation %.3e\n", worst);
  EXPECT_LE(worst, 1e-14);
  // Both rows: the innovation covariance is 2 x 2 and mu stays a distribution.
  full.predict();
  full.update(Eigen::Vector2d(30.0, 3.0), Eigen::Vector2d(1.0, 1.0));
  EXPECT_TRUE(full.last_update_applied());
  EXPECT_NEAR(full.mu().sum(), 1.0, 1e-15);
}

// Zero measurement noise and zero prior covariance make S = 0: the Cholesky fails. That is a
// status, and the filter keeps its priors (mu = cbar), with nothing NaN.
TEST(ImmFilter, NonPositiveDefiniteInnovationIsAStatusNotANaN) {
  ImmMode mode = peer_mode(0.0);
  mode.R.setZero();
  ImmFilter imm({mode, mode}, peer_transition(), Eigen::VectorXd::Zero(2),
                Eigen::MatrixXd::Zero(2, 2), Eigen::Vector2d(0.5, 0.5));
  imm.predict();
  imm.update(Eigen::Matrix<double, 1, 1>(1.0));
  EXPECT_EQ(imm.status(), ImmStatus::kInnovationNotPositiveDefinite);
  EXPECT_FALSE(imm.last_update_applied());
  EXPECT_EQ(imm.mu(), imm.cbar());
  EXPECT_TRUE(imm.x().allFinite() && imm.P().allFinite() && imm.mu().allFinite());
  EXPECT_EQ(imm.likelihood(0), 1.0);
  // A NaN measurement is refused the same way.
  ImmFilter nan_z = peer_filter(0.01, 1.0);
  nan_z.predict();
  nan_z.update(Eigen::Matrix<double, 1, 1>(std::nan("")));
  EXPECT_EQ(nan_z.status(), ImmStatus::kNonFiniteLikelihood);
  EXPECT_TRUE(nan_z.x().allFinite() && nan_z.mu().allFinite());
}

}  // namespace
}  // namespace ncosim::est
