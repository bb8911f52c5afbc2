// tests/estimators/imm_test.cc — the `imm` estimator kind: filterpy's two-mode tracker through
// a jump_linear plant scenario, missing measurements, mode estimate.
#include "estimators/imm.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "sim/scenario/scenario.h"

namespace ncosim::est {
namespace {

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
  auto next = [&] {
    if (!std::getline(in, line)) return false;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  };
  if (!next()) return csv;
  std::stringstream header(line);
  for (std::string cell; std::getline(header, cell, ',');) csv.column[cell] = csv.column.size();
  while (next()) {
    std::stringstream ss(line);
    std::vector<double> v;
    for (std::string cell; std::getline(ss, cell, ',');) v.push_back(std::stod(cell));
    csv.rows.push_back(std::move(v));
  }
  return csv;
}

// The peer system as a scenario: jump_linear plant x+ = F x + G w, w ~ N(0, q_mode),
// z = [1 0] x + v, R = 1; imm started at x = 0, P = 10 I, mu = (0.5, 0.5).
constexpr const char* kPeerScenario = R"(
[run]
periods = 201
[plant]
kind = "jump_linear"
A = [[1.0, 1.0], [0.0, 1.0]]
Bw = [[0.5], [1.0]]
W = [[0.01]]
transition = [[0.95, 0.05], [0.10, 0.90]]
[[plant.mode]]
W = [[0.01]]
[[plant.mode]]
W = [[1.0]]
[[sensor]]
C = [[1.0, 0.0]]
R = [[1.0]]
[[estimator]]
kind = "imm"
xhat0 = [0.0, 0.0]
P0 = [[10.0, 0.0], [0.0, 10.0]]
mode_prior = "uniform"
)";

std::unique_ptr<sim::Scenario> peer_scenario() {
  return sim::build_scenario(toml::parse(kPeerScenario, std::string_view("peer.toml")), "peer.toml",
                             ".");
}

Packet measurement(double z, std::int64_t k) {
  Packet p;
  p.sensor = 0;
  p.send_period = k;
  p.count = 1;
  p.stamps = {k};
  p.values = Eigen::VectorXd::Constant(1, z);
  return p;
}

// filterpy's step k (predict, update with z(k)) is our period k + 1: period 0 only sets the
// prior (no measurement), so after period k + 1 the filter must equal filterpy's row k. The
// posterior columns are compared to 1e-9 (relative to max(1, |value|)); x_prior is filterpy's
// quirk (combined with the previous mu) and is not compared.
TEST(Imm, KindMatchesFilterpyThroughAJumpLinearPlantAtEveryStep) {
  const Csv inputs = read_csv(NCOSIM_SOURCE_DIR "/tests/data/peers/imm_filterpy_inputs.csv");
  const Csv ref = read_csv(NCOSIM_SOURCE_DIR "/tests/data/peers/imm_filterpy_output.csv");
  ASSERT_EQ(inputs.rows.size(), 200U);
  ASSERT_EQ(ref.rows.size(), 200U);
  auto sc = peer_scenario();
  auto est = sc->estimators.front().design->instantiate();
  const ImmFilter* f = imm_filter_of(*est);
  ASSERT_NE(f, nullptr);
  const Eigen::VectorXd u(0), drive = Eigen::VectorXd::Zero(2);
  est->on_period(0, PeriodInput{u, drive});
  EXPECT_FALSE(est->mode().has_value());
  double worst = 0.0;
  std::string worst_what;
  auto check = [&](double got, double want, const std::string& what, std::size_t k) {
    const double err = std::abs(got - want) / std::max(1.0, std::abs(want));
    if (err > worst) {
      worst = err;
      worst_what = what + " at step " + std::to_string(k);
    }
  };
  for (std::size_t k = 0; k < 200; ++k) {
    const auto period = static_cast<std::int64_t>(k + 1);
    EXPECT_EQ(est->on_packet(measurement(inputs.at(k, "z"), period), period), 1);
    est->on_period(period, PeriodInput{u, drive});
    for (int j = 0; j < 2; ++j) {
      const std::string fj = "f" + std::to_string(j) + "_";
      check(f->mu()(j), ref.at(k, "mu" + std::to_string(j)), "mu", k);
      check(f->cbar()(j), ref.at(k, "cbar" + std::to_string(j)), "cbar", k);
      check(f->likelihood(j), ref.at(k, "lik" + std::to_string(j)), "lik", k);
      check(f->mode_x(j)(0), ref.at(k, fj + "x0"), fj + "x0", k);
      check(f->mode_x(j)(1), ref.at(k, fj + "x1"), fj + "x1", k);
      check(f->mode_P(j)(0, 0), ref.at(k, fj + "P00"), fj + "P00", k);
      check(f->mode_P(j)(0, 1), ref.at(k, fj + "P01"), fj + "P01", k);
      check(f->mode_P(j)(1, 1), ref.at(k, fj + "P11"), fj + "P11", k);
    }
    const auto x = est->state();
    const Eigen::MatrixXd& P = *est->covariance();
    check(x(0), ref.at(k, "x0"), "x0", k);
    check(x(1), ref.at(k, "x1"), "x1", k);
    check(P(0, 0), ref.at(k, "P00"), "P00", k);
    check(P(0, 1), ref.at(k, "P01"), "P01", k);
    check(P(1, 1), ref.at(k, "P11"), "P11", k);
    ASSERT_TRUE(est->mode().has_value());
    EXPECT_EQ(*est->mode(), ref.at(k, "mu1") > ref.at(k, "mu0") ? 1 : 0) << "step " << k;
  }
  EXPECT_LT(worst, 1e-9) << "worst: " << worst_what;
  std::printf("imm kind vs filterpy: worst relative difference %.3g (%s)\n", worst,
              worst_what.c_str());
  EXPECT_EQ(est->status(), "ok");
}

// A missing measurement is a prediction only: mu = cbar, each mode keeps its prior (not
// filterpy's update(None), which reuses the last innovation covariance). Worked out: from the
// state after 10 peer steps, a period without packet must leave mode j's x equal to F x0_j
// (the mixed estimate), and mu = M' mu_prev.
TEST(Imm, MissingMeasurementIsAPredictionWithMuEqualCbar) {
  const Csv inputs = read_csv(NCOSIM_SOURCE_DIR "/tests/data/peers/imm_filterpy_inputs.csv");
  ASSERT_EQ(inputs.rows.size(), 200U);
  auto sc = peer_scenario();
  auto est = sc->estimators.front().design->instantiate();
  const ImmFilter* f = imm_filter_of(*est);
  const Eigen::VectorXd u(0), drive = Eigen::VectorXd::Zero(2);
  est->on_period(0, PeriodInput{u, drive});
  for (std::int64_t k = 1; k <= 10; ++k) {
    est->on_packet(measurement(inputs.at(static_cast<std::size_t>(k - 1), "z"), k), k);
    est->on_period(k, PeriodInput{u, drive});
  }
  const Eigen::VectorXd mu_prev = f->mu();
  Eigen::Matrix2d M;
  M << 0.95, 0.05, 0.10, 0.90;
  est->on_period(11, PeriodInput{u, drive});
  const Eigen::Vector2d cbar = M.transpose() * mu_prev;
  EXPECT_NEAR(f->mu()(0), cbar(0), 1e-15);
  EXPECT_NEAR(f->mu()(1), cbar(1), 1e-15);
  EXPECT_EQ(f->likelihood(0), 1.0);
  EXPECT_FALSE(f->last_update_applied());
  // A late packet (stamped 10, arriving at 12) is not used by the mode estimator.
  EXPECT_EQ(est->on_packet(measurement(1.0, 10), 12), 0);
}

}  // namespace
}  // namespace ncosim::est
