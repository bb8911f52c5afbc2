// tests/estimators/jump_design_test.cc — the jump observer's offline design (Dolz et al. 2014).
#include "estimators/design/jump_design.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <numeric>

#include "estimators/extended_model.h"
#include "sim/scenario/registries.h"
#include "test_util.h"

namespace ncosim::est {
namespace {

using testing::dolz_model;

// E_L{P} of eq. (18) evaluated independently of the design loop, by summing over N up to a
// large horizon instead of using the closed-form tail: sum_N p0^(N-1) sum_i p_i
// [F (A^N P A^N' + S_W,N) F' + L eta V eta L'], with gains L(min(N, Nbar), i).
Eigen::MatrixXd expected_covariance(const ExtendedModel& ext, const std::vector<double>& prob,
                                    const JumpDesign& d, const Eigen::MatrixXd& P) {
  const Eigen::Index nb = ext.nb;
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(nb, nb);
  Eigen::MatrixXd AN = Eigen::MatrixXd::Identity(nb, nb);
  Eigen::MatrixXd SW = Eigen::MatrixXd::Zero(nb, nb);
  double p0N = 1.0;  // p0^(N-1)
  for (int N = 1; N < 2000 && p0N > 1e-300; ++N) {
    SW += AN * ext.Q * AN.transpose();
    AN = ext.A * AN;
    const Eigen::MatrixXd X = AN * P * AN.transpose() + SW;
    for (std::size_t m = 1; m < prob.size(); ++m) {
      const Eigen::MatrixXd LE =
          d.gains[d.gain_of[std::min(N, d.Nbar) - 1][m]] * ext.row_mask(m).asDiagonal();
      const Eigen::MatrixXd F = Eigen::MatrixXd::Identity(nb, nb) - LE * ext.C;
      out += p0N * prob[m] * (F * X * F.transpose() + LE * ext.V * LE.transpose());
    }
    p0N *= d.p0;
  }
  return out;
}

TEST(JumpDesign, StoredGainsFollowTheGroupingCountsOfSection5) {
  // A3 with two sensors and dbar = 1: 4 fictitious sensors, 15 patterns.
  // |L_S1| = Nbar, |L_S2| = n_m Nbar = 2 Nbar, |L_S3| = nbar_m Nbar = 4 Nbar, |L_S4| = 15 Nbar.
  auto d = dolz_model();
  const ExtendedModel ext = build_extended(d.model, 1);
  const auto prob = pattern_probabilities(d.model, ext);
  EXPECT_EQ(design_jump_iterative(ext, prob, 1, Grouping::kS1).stored_gains, 1);
  EXPECT_EQ(design_jump_iterative(ext, prob, 1, Grouping::kS2).stored_gains, 2);
  EXPECT_EQ(design_jump_iterative(ext, prob, 1, Grouping::kS3).stored_gains, 4);
  EXPECT_EQ(design_jump_iterative(ext, prob, 2, Grouping::kS3).stored_gains, 8);
  EXPECT_EQ(design_jump_iterative(ext, prob, 4, Grouping::kS4).stored_gains, 60);
}

TEST(JumpDesign, PatternProbabilitiesAreTheProductOfTable1Probabilities) {
  // eq. (14): p0 = (1-0.3340)(1-0.3064)(1-0.3761)(1-0.3403) = 0.190127...
  // eq. (15): P[only fictitious sensor (2, delay 1)] = 0.666 * 0.6936 * 0.6239 * 0.3403.
  auto d = dolz_model();
  const ExtendedModel ext = build_extended(d.model, 1);
  const auto prob = pattern_probabilities(d.model, ext);
  ASSERT_EQ(prob.size(), 16U);
  EXPECT_NEAR(std::accumulate(prob.begin(), prob.end(), 0.0), 1.0, 1e-14);
  EXPECT_NEAR(prob[0], 0.666 * 0.6936 * 0.6239 * 0.6597, 1e-12);
  EXPECT_NEAR(prob[0b1000], 0.666 * 0.6936 * 0.6239 * 0.3403, 1e-12);
  EXPECT_NEAR(prob[0b1111], 0.3340 * 0.3064 * 0.3761 * 0.3403, 1e-12);
}

TEST(JumpDesign, BufferedPacketDeliversItsFictitiousSensorsTogether) {
  // One sensor, buffer 1, delay 0 with probability 0.6, dbar = 1. A packet sent now carries
  // samples k and k-1 (bits 0 and 1); a packet sent one period ago would need delay 1 (prob 0).
  // So P[0b11] = 0.6, P[0] = 0.4 and the single-bit patterns never occur.
  auto d = dolz_model({{0.6}});
  d.model.sensors[0].spec.buffer = 1;
  const ExtendedModel ext = build_extended(d.model, 1);
  const auto prob = pattern_probabilities(d.model, ext);
  EXPECT_NEAR(prob[0b11], 0.6, 1e-15);
  EXPECT_NEAR(prob[0], 0.4, 1e-15);
  EXPECT_EQ(prob[0b01], 0.0);
  EXPECT_EQ(prob[0b10], 0.0);
}

TEST(JumpDesign, IterationConvergesToAFixedPointOfTheCovarianceOperator) {
  // For every grouping the returned P must satisfy P = E_L{P} (eq. 18) with the returned
  // gains, evaluated here by brute-force summation over N (not the closed-form tail).
  auto d = dolz_model();
  const ExtendedModel ext = build_extended(d.model, 1);
  const auto prob = pattern_probabilities(d.model, ext);
  for (auto [g, Nbar] :
       {std::pair{Grouping::kS1, 1}, {Grouping::kS2, 1}, {Grouping::kS3, 2}, {Grouping::kS4, 4}}) {
    const JumpDesign jd = design_jump_iterative(ext, prob, Nbar, g);
    ASSERT_TRUE(jd.stable) << jd.status;
    const Eigen::MatrixXd E = expected_covariance(ext, prob, jd, jd.P);
    EXPECT_LT((E - jd.P).cwiseAbs().maxCoeff(), 1e-10 * jd.P.cwiseAbs().maxCoeff())
        << "grouping " << static_cast<int>(g)
        << ": |E{P} - P| = " << (E - jd.P).cwiseAbs().maxCoeff();
  }
}

TEST(JumpDesign, MoreGainsNeverPredictAWorseCovariance) {
  // S4 is optimal per term, so tr(Pt) must order S4 <= S3 <= S2 <= S1 at equal Nbar,
  // and S4 with Nbar = 4 <= S4 with Nbar = 1.
  auto d = dolz_model();
  const ExtendedModel ext = build_extended(d.model, 1);
  const auto prob = pattern_probabilities(d.model, ext);
  auto tr = [&](Grouping g, int Nbar) {
    return design_jump_iterative(ext, prob, Nbar, g).Pt.trace();
  };
  const double s1 = tr(Grouping::kS1, 1), s2 = tr(Grouping::kS2, 1), s3 = tr(Grouping::kS3, 1);
  const double s4 = tr(Grouping::kS4, 1), s4n4 = tr(Grouping::kS4, 4);
  EXPECT_LE(s4, s3 + 1e-12);
  EXPECT_LE(s3, s2 + 1e-12);
  EXPECT_LE(s2, s1 + 1e-12);
  EXPECT_LE(s4n4, s4 + 1e-12);
  std::printf("tr(Pt): S1 %.5f  S2 %.5f  S3 %.5f  S4 %.5f  S4(Nbar=4) %.5f\n", s1, s2, s3, s4,
              s4n4);
}

TEST(JumpDesign, NoLossReducesToTheSteadyStateKalmanFilter) {
  // One sensor, dbar = 0, delay 0 with probability 1: p0 = 0, every period updates, and the
  // S4 gain must be the stationary Kalman gain: P = Riccati posterior fixed point.
  auto d = dolz_model({{1.0}});
  const ExtendedModel ext = build_extended(d.model, 0);
  const auto prob = pattern_probabilities(d.model, ext);
  ASSERT_EQ(prob[0], 0.0);
  const JumpDesign jd = design_jump_iterative(ext, prob, 1, Grouping::kS4);
  ASSERT_TRUE(jd.stable);
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(2, 2);  // posterior Riccati iteration
  const auto& A = ext.A;
  for (int i = 0; i < 5000; ++i) {
    const Eigen::MatrixXd Pm = A * P * A.transpose() + ext.Q;
    const Eigen::MatrixXd S = ext.C * Pm * ext.C.transpose() + ext.V;
    P = Pm - Pm * ext.C.transpose() * S.inverse() * ext.C * Pm;
  }
  EXPECT_LT((jd.P - P).cwiseAbs().maxCoeff(), 1e-12) << "design P\n" << jd.P << "\nRiccati\n" << P;
  EXPECT_NEAR(jd.Pt.trace(), P.trace(), 1e-12);
}

TEST(JumpDesign, UnstableWhenTheNoMeasurementProbabilityIsTooHigh) {
  // A3 has rho = 1.6352; with p0 = 0.9^2 = 0.81 (both sensors lost w.p. 0.9):
  // p0 rho^2 = 2.17 >= 1, so no finite covariance exists: status, not a throw or NaN gain.
  auto d = dolz_model({{0.1}, {0.1}});
  const ExtendedModel ext = build_extended(d.model, 0);
  const JumpDesign jd =
      design_jump_iterative(ext, pattern_probabilities(d.model, ext), 1, Grouping::kS4);
  EXPECT_FALSE(jd.stable);
  EXPECT_NE(jd.status.find("unstable"), std::string::npos) << jd.status;
}

TEST(JumpDesign, ASlowButConvergingIterationIsNotTakenForAStall) {
  // A slowly decaying plant whose sensors say little (R = 1e4): the iteration contracts by about
  // a^2 per step, so it needs tens of thousands of steps, many stall windows of 2000. Diagonal,
  // and a Jordan block whose changes first grow (about k^2 a^(2k)). Both must run to their fixed
  // point, not stop as stalled.
  for (const bool jordan : {false, true}) {
    auto d = dolz_model({{1.0}, {1.0}});
    d.model.plant.A << 0.9997, jordan ? 0.01 : 0.0, 0.0, jordan ? 0.9997 : 0.5;
    for (auto& sensor : d.model.sensors) sensor.spec.R(0, 0) = 1e4;
    const ExtendedModel ext = build_extended(d.model, 0);
    const JumpDesign jd =
        design_jump_iterative(ext, pattern_probabilities(d.model, ext), 1, Grouping::kS4);
    EXPECT_EQ(jd.status, "ok") << "jordan " << jordan;
    EXPECT_EQ(jd.iteration_message, "") << "jordan " << jordan;
    EXPECT_GT(jd.iterations, 3 * 2000)
        << "jordan " << jordan << ": not slow enough to cross several stall windows";
    EXPECT_LT(jd.iterations, 200000) << "jordan " << jordan;
  }
}

TEST(JumpDesign, FlopsAreThePaperFormulaForA3) {
  // Dolz et al. section 2 with nb = 4, nu = 1, nw = 2, nmb = 4:
  // jump 16 + 4 + 32 + 8 + 4 = 64; Kalman 128 + 32 + 16 + 256 + 128 + 320 + 32 + 4 + 32 + 16 + 8 +
  // 4 = 976.
  auto d = dolz_model();
  const auto& reg = sim::estimator_registry();
  toml::table jt{{"grouping", "S4"}, {"history", 4}, {"max_delay", 1}};
  toml::table kt{{"max_delay", 1}};
  const auto jump = reg.find("jump")->factory(config::Table(jt, "estimator[0]", "test"), d.model);
  const auto kf =
      reg.find("kalman_extended")->factory(config::Table(kt, "estimator[1]", "test"), d.model);
  EXPECT_EQ(jump->flops_per_period().value(), 64.0);
  EXPECT_EQ(kf->flops_per_period().value(), 976.0);
  EXPECT_EQ(jump->report().stored_gains.value(), 60);
}

TEST(JumpDesign, PaperEq28AsPrintedIsKeptApartFromTheCorrectedForm) {
  // Printed (28): (1-p0) P + p0 sum_k p0^k Abar^k (Abar P Abar' + Q/(1-p0)) Abar^k'; corrected:
  // (1-p0) P + p0 ((1-p0) Abar S_P Abar' + S'_W,inf). Summed here term by term (k < 4000,
  // p0 rho(Abar)^2 < 1 so the tail is below 1e-12), then the printed form must exceed the
  // corrected one (its N >= 1 terms lack the factor 1-p0 < 1).
  auto d = dolz_model();
  const ExtendedModel ext = build_extended(d.model, 1);
  const auto prob = pattern_probabilities(d.model, ext);
  const JumpDesign jd = design_jump_iterative(ext, prob, 4, Grouping::kS4);
  ASSERT_TRUE(jd.stable);
  const double p0 = jd.p0;
  // term_k = p0^k Abar^k Sc Abar^k', built as term_{k+1} = p0 Abar term_k Abar' (no overflow).
  Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(ext.nb, ext.nb);
  Eigen::MatrixXd term = ext.A * jd.P * ext.A.transpose() + ext.Q / (1.0 - p0);
  for (int k = 0; k < 4000; ++k) {
    sum += term;
    term = p0 * ext.A * term * ext.A.transpose();
  }
  const Eigen::MatrixXd printed = (1.0 - p0) * jd.P + p0 * sum;
  EXPECT_LT((printed - jd.Pt_paper_eq28_erroneous).cwiseAbs().maxCoeff(),
            1e-10 * printed.cwiseAbs().maxCoeff());
  EXPECT_GT(jd.Pt_paper_eq28_erroneous.trace(), 1.01 * jd.Pt.trace());
  std::printf("A3, S4, Nbar = 4: tr Pt corrected %.6f, printed (28) %.6f\n", jd.Pt.trace(),
              jd.Pt_paper_eq28_erroneous.trace());
}

}  // namespace
}  // namespace ncosim::est
