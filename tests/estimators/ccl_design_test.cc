// tests/estimators/ccl_design_test.cc — the paper's CCL design (section 4) on the LMI layer,
// and the common evaluation of designed gains (evaluate_jump_gains).
#include "estimators/design/ccl_design.h"

#include <gtest/gtest.h>

#include "estimators/design/jump_design.h"
#include "estimators/extended_model.h"
#include "test_util.h"

namespace ncosim::est {
namespace {

using testing::dolz_model;

TEST(CclDesign, EvaluationOfTheIterativeGainsReproducesTheIterativePrediction) {
  // Both methods report through evaluate_jump_gains: on the iterative gains it must agree
  // with the value iteration's own fixed point (A3, dbar = 1, every grouping).
  auto d = dolz_model();
  const ExtendedModel ext = build_extended(d.model, 1);
  const auto prob = pattern_probabilities(d.model, ext);
  for (auto [g, Nbar] : {std::pair{Grouping::kS1, 1}, {Grouping::kS3, 2}, {Grouping::kS4, 3}}) {
    const JumpDesign it = design_jump_iterative(ext, prob, Nbar, g);
    ASSERT_TRUE(it.stable);
    const JumpDesign ev = evaluate_jump_gains(ext, prob, Nbar, g, it.gains);
    ASSERT_TRUE(ev.stable) << ev.status;
    EXPECT_NEAR(ev.Pt.trace(), it.Pt.trace(), 1e-9 * it.Pt.trace());
    EXPECT_LT((ev.P - it.P).norm(), 1e-9 * it.P.norm());
  }
}

TEST(CclDesign, UnstableGainsAreReportedNotEvaluated) {
  auto d = dolz_model();
  const ExtendedModel ext = build_extended(d.model, 0);
  // dbar = 0 (3 patterns); each sensor delivers with probability 0.8, independently.
  const std::vector<double> prob = {0.04, 0.16, 0.16, 0.64};
  // Zero gains leave A3 (rho = 1.64) open loop: no fixed point.
  const std::vector<Eigen::MatrixXd> zero(3, Eigen::MatrixXd::Zero(ext.nb, ext.nmb));
  const JumpDesign ev = evaluate_jump_gains(ext, prob, 1, Grouping::kS4, zero);
  EXPECT_FALSE(ev.stable);
  EXPECT_EQ(ev.status, "unstable_gains");
}

TEST(CclDesign, IterativeS4IsNeverWorseThanCclS4AndCclIsAboveItsLowerBound) {
  // The iterative S4 design is the exact optimum; the CCL bisection can only approach it. By
  // default CCL starts its first linearisation and its lower end at that optimum; without it
  // (s4_bound = false) CCL starts from the LMI relaxation alone and must still get there.
  auto d = dolz_model();
  const ExtendedModel ext = build_extended(d.model, 0);
  // dbar = 0 (3 patterns); each sensor delivers with probability 0.8, independently.
  const std::vector<double> prob = {0.04, 0.16, 0.16, 0.64};
  for (bool anchored : {true, false}) {
    for (int Nbar : {1, 2}) {
      CclOptions o;
      o.s4_bound = anchored;
      CclInfo info;
      const JumpDesign ccl = design_jump_ccl(ext, prob, Nbar, Grouping::kS4, o, &info);
      ASSERT_TRUE(ccl.stable) << ccl.status;
      const JumpDesign it =
          evaluate_jump_gains(ext, prob, Nbar, Grouping::kS4,
                              design_jump_iterative(ext, prob, Nbar, Grouping::kS4).gains);
      SCOPED_TRACE(::testing::Message()
                   << "Nbar " << Nbar << (anchored ? " anchored" : " from the relaxation"));
      EXPECT_LE(it.Pt.trace(), ccl.Pt.trace() * (1.0 + 1e-9));
      EXPECT_LE(it.P.trace(), ccl.P.trace() * (1.0 + 1e-9));
      // tr(P) of the CCL gains lies between the bisection's certified lower end and its upper
      // end, and the bisection closed its gap.
      EXPECT_LE(info.lower_bound, ccl.P.trace() * (1.0 + 1e-9));
      if (anchored) {
        EXPECT_NEAR(info.s4_bound, it.P.trace(), 1e-9 * it.P.trace());
        EXPECT_EQ(info.relaxation_bound, 0.0);
      } else {
        EXPECT_EQ(info.s4_bound, 0.0);
        EXPECT_GT(info.relaxation_bound, 0.0);
        EXPECT_LE(info.relaxation_bound, it.P.trace());
        EXPECT_GT(info.sdp_solves, 2);
      }
      EXPECT_NEAR(info.upper_bound, ccl.P.trace(), 1e-12);
      // The bisection closed its gap, or (anchored only) stopped after two steps that found
      // nothing better.
      if (anchored && info.stopped_fruitless) {
        EXPECT_GE(info.bisections, 2);
      } else {
        EXPECT_FALSE(info.stopped_fruitless);
        EXPECT_LT(info.upper_bound - info.lower_bound, 1e-3 * info.upper_bound + 1e-12);
      }
      EXPECT_GE(info.sdp_solves, 1);
      EXPECT_GT(info.size.variables, 0);
      // On this small case CCL reaches the exact optimum closely (measured: within 0.1 %).
      EXPECT_LT(ccl.Pt.trace(), 1.01 * it.Pt.trace());
    }
  }
}

TEST(CclDesign, SharedGainsHonourTheGroupingEqualities) {
  // S1: one gain per N shared by every pattern; the design returns one gain per N.
  auto d = dolz_model();
  const ExtendedModel ext = build_extended(d.model, 0);
  // dbar = 0 (3 patterns); each sensor delivers with probability 0.8, independently.
  const std::vector<double> prob = {0.04, 0.16, 0.16, 0.64};
  CclInfo info;
  const JumpDesign ccl = design_jump_ccl(ext, prob, 2, Grouping::kS1, {}, &info);
  ASSERT_TRUE(ccl.stable) << ccl.status;
  // The exact S4 design bounds every grouping from below.
  EXPECT_GT(info.s4_bound, 0.0);
  EXPECT_LT(info.s4_bound, ccl.P.trace());
  EXPECT_EQ(ccl.gains.size(), 2U);
  EXPECT_EQ(ccl.stored_gains, 2);
  for (std::size_t m = 1; m < prob.size(); ++m) {
    EXPECT_EQ(ccl.gain_of[0][m], 0);
    EXPECT_EQ(ccl.gain_of[1][m], 1);
  }
}

TEST(CclDesign, MomentFormOfSharedGainsIsExactAndSmaller) {
  // A group of patterns sharing a gain enters through the mean and covariance of its
  // availability vector instead of one LMI term per pattern. The two SDPs have the same
  // feasible set: the relaxation optimum (min tr P) must agree, on A3 with dbar = 1 (15
  // patterns), and the moment form must be the smaller SDP.
  auto d = dolz_model();
  const ExtendedModel ext = build_extended(d.model, 1);
  const auto prob = pattern_probabilities(d.model, ext);
  for (auto [g, Nbar] : {std::pair{Grouping::kS1, 2}, {Grouping::kS2, 1}, {Grouping::kS3, 1}}) {
    CclOptions moments, per_pattern;
    moments.max_bisections = per_pattern.max_bisections = 0;   // relaxation and first gains only
    moments.s4_bound = per_pattern.s4_bound = false;           // solve the relaxation
    moments.sdp_tolerance = per_pattern.sdp_tolerance = 1e-8;  // accurate optima to compare
    per_pattern.group_moments = false;
    CclInfo a, b;
    const JumpDesign dm = design_jump_ccl(ext, prob, Nbar, g, moments, &a);
    const JumpDesign dp = design_jump_ccl(ext, prob, Nbar, g, per_pattern, &b);
    ASSERT_TRUE(dm.stable && dp.stable) << dm.status << " " << dp.status;
    EXPECT_NEAR(a.relaxation_bound, b.relaxation_bound, 1e-5 * b.relaxation_bound)
        << "grouping " << static_cast<int>(g);
    EXPECT_LT(a.size.total_dimension, b.size.total_dimension);
    // The SDPs are solved on the model with its noise normalised (P scales, the gains do not):
    // the relaxation bound, mapped back, is the unnormalised one.
    CclOptions raw = moments;
    raw.normalise = false;
    CclInfo c;
    design_jump_ccl(ext, prob, Nbar, g, raw, &c);
    EXPECT_NEAR(a.relaxation_bound, c.relaxation_bound, 1e-5 * c.relaxation_bound);
  }
  // The relaxation leaves Q, R free (the A^N parts drop out of its optimum), so also compare
  // the first CCL step, linearised at the S4 optimum, where every part of each term counts:
  // the same SDP must give the same gains.
  for (auto [g, Nbar] : {std::pair{Grouping::kS1, 2}, {Grouping::kS2, 1}, {Grouping::kS3, 2}}) {
    CclOptions moments, per_pattern;
    moments.max_bisections = per_pattern.max_bisections = 0;
    moments.sdp_tolerance = per_pattern.sdp_tolerance = 1e-9;
    per_pattern.group_moments = false;
    const JumpDesign dm = design_jump_ccl(ext, prob, Nbar, g, moments);
    const JumpDesign dp = design_jump_ccl(ext, prob, Nbar, g, per_pattern);
    ASSERT_TRUE(dm.stable && dp.stable);
    // Equal to the SDP's accuracy (measured: 1.5e-6 relative); a missing or misweighted part of
    // a term changes it by percents.
    EXPECT_NEAR(dm.Pt.trace(), dp.Pt.trace(), 1e-5 * dp.Pt.trace())
        << "grouping " << static_cast<int>(g);
    for (std::size_t i = 0; i < dm.gains.size(); ++i)
      EXPECT_LT((dm.gains[i] - dp.gains[i]).norm(), 1e-4 * (1.0 + dp.gains[i].norm()));
  }
}

TEST(CclDesign, SharedGainCclReachesTheIterationWithOrWithoutTheS4Anchor) {
  // Table 2's shared-gain cases (A3, dbar = 1, Nbar = 1): CCL's designs, anchored at the exact
  // S4 optimum (default) or started from the LMI relaxation alone, land within 0.1 % of the
  // shared-gain iteration's tr(Pt) (measured: at most 0.024 %), i.e. two independent methods agree.
  auto d = dolz_model();
  const ExtendedModel ext = build_extended(d.model, 1);
  const auto prob = pattern_probabilities(d.model, ext);
  for (Grouping g : {Grouping::kS1, Grouping::kS2, Grouping::kS3}) {
    const JumpDesign it =
        evaluate_jump_gains(ext, prob, 1, g, design_jump_iterative(ext, prob, 1, g).gains);
    for (bool anchored : {true, false}) {
      CclOptions o;
      o.s4_bound = anchored;
      const JumpDesign ccl = design_jump_ccl(ext, prob, 1, g, o);
      ASSERT_TRUE(ccl.stable) << ccl.status;
      EXPECT_NEAR(ccl.Pt.trace(), it.Pt.trace(), 1e-3 * it.Pt.trace())
          << "S" << static_cast<int>(g) + 1 << (anchored ? " anchored" : " from the relaxation");
    }
  }
}

TEST(CclDesign, LosslessNetworkWithHistoryHasNoEmptyTerms) {
  // p0 = 0: an update every period, so no term of (18) has N >= 2 and those gains carry no
  // weight. They must get no variables (a zero-weight group would put 0/0 into the SDP).
  auto d = dolz_model();
  const ExtendedModel ext = build_extended(d.model, 0);
  const std::vector<double> prob = {0.0, 0.2, 0.2, 0.6};
  for (Grouping g : {Grouping::kS1, Grouping::kS3, Grouping::kS4}) {
    for (bool anchored : {true, false}) {
      CclOptions o;
      o.s4_bound = anchored;
      const JumpDesign ccl = design_jump_ccl(ext, prob, 2, g, o);
      ASSERT_TRUE(ccl.stable) << ccl.status;
      ASSERT_TRUE(ccl.Pt.allFinite());
      const JumpDesign it =
          evaluate_jump_gains(ext, prob, 2, g, design_jump_iterative(ext, prob, 2, g).gains);
      EXPECT_NEAR(ccl.Pt.trace(), it.Pt.trace(), 1e-3 * it.Pt.trace())
          << static_cast<int>(g) << " " << anchored;
    }
  }
}

TEST(CclDesign, AnUnstableNetworkIsAStatusNotACrash) {
  auto d = dolz_model();
  const ExtendedModel ext = build_extended(d.model, 0);
  std::vector<double> prob = {0.9, 0.05, 0.03, 0.02};  // p0 rho^2 = 0.9 * 2.67 > 1
  const JumpDesign ccl = design_jump_ccl(ext, prob, 1, Grouping::kS4);
  EXPECT_FALSE(ccl.stable);
  EXPECT_EQ(ccl.status.rfind("unstable", 0), 0U) << ccl.status;
}

TEST(CclDesign, AFailedSdpIsTheDesignStatus) {
  // CSDP stopped after one iteration: numerical_trouble becomes the design's status (the
  // estimator row then reads design_numerical_trouble), with no gains and no prediction.
  auto d = dolz_model();
  const ExtendedModel ext = build_extended(d.model, 0);
  const std::vector<double> prob = {0.04, 0.16, 0.16, 0.64};
  CclOptions o;
  o.sdp_max_iterations = 1;
  o.s4_bound = false;  // the first SDP is then the relaxation, which needs more than one iteration
  CclInfo info;
  const JumpDesign ccl = design_jump_ccl(ext, prob, 1, Grouping::kS4, o, &info);
  EXPECT_FALSE(ccl.stable);
  EXPECT_EQ(ccl.status, "numerical_trouble");
  EXPECT_EQ(info.lmi_status, "numerical_trouble");
  EXPECT_EQ(info.sdp_solves, 1);
}

}  // namespace
}  // namespace ncosim::est
