// tests/estimators/kalman_extended_test.cc — the Kalman filter on the delay-extended model.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "sim/scenario/registries.h"
#include "test_util.h"

namespace ncosim::est {
namespace {

std::unique_ptr<EstimatorDesign> make(const std::string& kind, toml::table t, const Model& model) {
  return sim::estimator_registry().find(kind)->factory(config::Table(t, "estimator[0]", "test"),
                                                       model);
}

Packet packet(int sensor, std::int64_t stamp, const Eigen::VectorXd& y) {
  Packet p;
  p.sensor = sensor;
  p.send_period = stamp;
  p.count = 1;
  p.stamps = {stamp};
  p.values = y;
  return p;
}

// Peer vectors (tests/data/peers/kf_intermittent_filterpy.csv, filterpy 1.4.5): Sinopoli's
// intermittent Kalman filter, A = [[1.25, 1], [0, 1.1]], C = [1 0], Q = 0.2 I, R = 0.5,
// xhat0 = 0, P0 = I, 500 steps. Row k is the posterior after predict + (update if gamma) of
// step k; here the initial estimate is period 0, so row k is our period k + 1. With
// max_delay = 0 kalman_extended is exactly that filter.
TEST(KalmanExtended, MatchesFilterpyIntermittentObservationsStepByStep) {
  toml::table t{{"max_delay", 0},
                {"P0", toml::array{toml::array{1.0, 0.0}, toml::array{0.0, 1.0}}}};
  const auto design = make("kalman_extended", t, testing::kf_peer_model());
  auto kf = design->instantiate();
  const testing::PeerReplay r = testing::replay_kf_peer(*kf);
  ASSERT_EQ(r.rows, 500) << "peer vectors not found or malformed";
  EXPECT_LT(r.worst, 1e-9) << r.where;
  std::printf("worst relative deviation over %d steps: %.3g\n", r.rows, r.worst);
}

// A static scalar plant (A = I, Q = 0) seen directly (C = 1, R = 1) by one sensor.
Model static_model(int buffer) {
  Model model;
  model.plant.A = Eigen::MatrixXd::Identity(1, 1);
  model.plant.Bu = Eigen::MatrixXd::Zero(1, 0);
  model.plant.Bw = Eigen::MatrixXd::Identity(1, 1);
  model.plant.W = Eigen::MatrixXd::Zero(1, 1);
  model.plant.x0 = Eigen::VectorXd::Zero(1);
  SensorModel s;
  s.spec.C = Eigen::MatrixXd::Identity(1, 1);
  s.spec.R = Eigen::MatrixXd::Constant(1, 1, 1.0);
  s.spec.buffer = buffer;
  model.sensors.push_back(s);
  return model;
}

// A static plant (A = I, Q = 0): one sample y of x0 ~ N(0, P0) gives the same posterior mean
// whether it arrives with delay 0 or delay 1 (the extended filter smooths x[k-1] = x[k]).
TEST(KalmanExtended, LateSampleGivesTheSamePosteriorOnAStaticPlant) {
  const Model model = static_model(0);
  toml::table t{{"max_delay", 1}, {"P0", 4.0}};
  const auto design = make("kalman_extended", t, model);
  const Eigen::VectorXd u0(0), drive = Eigen::VectorXd::Zero(1);
  // Posterior mean of x with prior N(0, 4) and y = 2.5, R = 1: 4/(4+1) * 2.5 = 2.
  auto now = design->instantiate();
  now->on_packet(packet(0, 0, Eigen::VectorXd::Constant(1, 2.5)), 0);
  now->on_period(0, PeriodInput{u0, drive});
  now->on_period(1, PeriodInput{u0, drive});
  auto late = design->instantiate();
  late->on_period(0, PeriodInput{u0, drive});
  late->on_packet(packet(0, 0, Eigen::VectorXd::Constant(1, 2.5)), 1);
  late->on_period(1, PeriodInput{u0, drive});
  EXPECT_NEAR(now->state()(0), 2.0, 1e-12);
  EXPECT_NEAR(late->state()(0), 2.0, 1e-12);
  // A sample older than max_delay is discarded: not used, state stays at the prior.
  auto old = design->instantiate();
  old->on_period(0, PeriodInput{u0, drive});
  old->on_period(1, PeriodInput{u0, drive});
  EXPECT_EQ(old->on_packet(packet(0, 0, Eigen::VectorXd::Constant(1, 2.5)), 2), 0);
  old->on_period(2, PeriodInput{u0, drive});
  EXPECT_EQ(old->state()(0), 0.0);
}

TEST(KalmanExtended, DuplicateBufferedSampleIsIgnored) {
  // Buffered packets repeat samples; a repeat must not be used twice (Dolz Remark 2.2).
  const Model model = static_model(1);
  toml::table t{{"max_delay", 1}, {"P0", 4.0}};
  const auto design = make("kalman_extended", t, model);
  auto kf = design->instantiate();
  const Eigen::VectorXd u0(0), drive = Eigen::VectorXd::Zero(1);
  EXPECT_EQ(kf->on_packet(packet(0, 0, Eigen::VectorXd::Constant(1, 2.5)), 0), 1);
  kf->on_period(0, PeriodInput{u0, drive});
  Packet p;
  p.sensor = 0;
  p.count = 2;
  p.stamps = {1, 0};
  p.values = Eigen::Vector2d(2.5, 2.5);
  EXPECT_EQ(kf->on_packet(p, 1), 1);  // only sample 1 is new
}

}  // namespace
}  // namespace ncosim::est

namespace ncosim::est {
namespace {

TEST(KalmanExtended, SemidefiniteInnovationUsesThePseudoInverse) {
  // R = 0 and P0 = 0: at k = 0 the innovation covariance S = C P C' + R = 0. The filter must
  // not skip or fail: K = P C' S^+ = 0 leaves the (exact) prior, status stays ok. One period
  // later P = Q = 1 > 0, S = 1 and a noiseless sample y = 3 sets xhat = 3 exactly.
  Model model = static_model(0);
  model.plant.W = Eigen::MatrixXd::Constant(1, 1, 1.0);
  model.sensors[0].spec.R = Eigen::MatrixXd::Zero(1, 1);
  toml::table t{{"max_delay", 0}};
  const auto design = make("kalman_extended", t, model);
  auto kf = design->instantiate();
  const Eigen::VectorXd u0(0), drive = Eigen::VectorXd::Zero(1);
  kf->on_packet(packet(0, 0, Eigen::VectorXd::Constant(1, 0.0)), 0);
  kf->on_period(0, PeriodInput{u0, drive});
  EXPECT_EQ(kf->state()(0), 0.0);
  kf->on_packet(packet(0, 1, Eigen::VectorXd::Constant(1, 3.0)), 1);
  kf->on_period(1, PeriodInput{u0, drive});
  EXPECT_NEAR(kf->state()(0), 3.0, 1e-15);
  EXPECT_NEAR((*kf->covariance())(0, 0), 0.0, 1e-15);
  EXPECT_EQ(kf->status(), "ok");
}

}  // namespace
}  // namespace ncosim::est
