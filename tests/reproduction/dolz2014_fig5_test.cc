// tests/reproduction/dolz2014_fig5_test.cc — Dolz et al. (2014), example 3, Fig. 5: the minimum
// delivery probability of sensor 1 (A3, buffered packets) with tr(Pt) <= 0.03, found by the
// `ncosim find` search on scenarios/dolz2014_fig5.toml. tr(Pt) is the plant-state block
// (predicted_mse): with b = 3 the extended-state trace grows with b and 0.03 would be out of reach
// (checked for this project).
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <sstream>

#include "sim/analysis/output.h"
#include "sim/cmd/find.h"
#include "sim/run/campaign.h"
#include "test_util.h"

namespace ncosim::sim {
namespace {

FindResult search() {
  FindOptions opt;
  opt.key = "link[0].delivery";
  opt.target = parse_target("predicted_mse<=0.03", "test");
  opt.lo = 0.5;
  opt.hi = 1.0;
  opt.tol = 1e-5;
  std::ostringstream log;
  FindResult r = find_threshold(testing::source_path("scenarios/dolz2014_fig5.toml"), {}, opt, log);
  EXPECT_EQ(log.str(), "") << "no warning expected (monotone, one crossing)";
  return r;
}

double threshold(const FindResult& r, const std::string& name) {
  for (const auto& row : r.rows) {
    if (row.estimator == name) {
      EXPECT_EQ(row.status, "ok") << name;
      EXPECT_TRUE(row.monotone) << name;
      EXPECT_TRUE(row.threshold.has_value()) << name;
      EXPECT_LE(*row.value, 0.03) << name;
      EXPECT_LE(*row.other - *row.threshold, 1e-5 + 1e-12) << name;
      return row.threshold.value_or(-1.0);
    }
  }
  ADD_FAILURE() << "no row " << name;
  return -1.0;
}

TEST(DolzFig5, ThresholdsOfTheMinimumDeliveryProbability) {
  const FindResult r = search();
  ASSERT_TRUE(r.sweeps.empty()) << "the swept delivery axis is searched, not swept";
  const double n1b0 = threshold(r, "S4 N1 b0"), n4b0 = threshold(r, "S4 N4 b0");
  const double n1b3 = threshold(r, "S4 N1 b3"), n4b3 = threshold(r, "S4 N4 b3");
  std::printf(
      "thresholds: N1 b0 %.5f (paper 0.9730), N4 b0 %.5f, N1 b3 %.5f, N4 b3 %.5f (paper 0.8530)\n",
      n1b0, n4b0, n1b3, n4b3);
  // N = 1, b = 0: one fictitious sensor and one gain per N: the paper's design and ours solve
  // the same problem, and the thresholds agree.
  EXPECT_NEAR(n1b0, 0.9730, 0.005);
  // More history and a longer buffer need less network: the paper's ordering.
  EXPECT_LT(n4b0, n1b0);
  EXPECT_LT(n1b3, n1b0);
  EXPECT_LT(n4b3, n1b3);
  EXPECT_LT(n4b3, n4b0);
  // N = 4, b = 3: the exact S4 design (value iteration, optimal in the matrix order for S4)
  // reaches 0.03 at a lower probability than the paper's CCL design (a heuristic). Documented in
  // results/README.md ("Fig. 5"): the paper's 0.8530 is sufficient, not minimal.
  EXPECT_LT(n4b3, 0.8530 - 0.005);
}

TEST(DolzFig5, AtThePapersProbabilityTheExactDesignIsBelowTarget) {
  // The paper's 0.8530 for N = 4, b = 3 already gives tr(Pt) < 0.03 under the exact design.
  auto sc = testing::load_one(testing::source_path("scenarios/dolz2014_fig5.toml"),
                              {"sweep[0].values=[0.853]"});
  bool seen = false;
  for (const auto& e : sc->estimators) {
    if (e.name != "S4 N4 b3") continue;
    seen = true;
    const auto& rep = e.design->report();
    ASSERT_TRUE(rep.predicted_mse.has_value());
    std::printf("S4 N4 b3 at 0.853: predicted tr(Pt) plant block %.5f\n", *rep.predicted_mse);
    EXPECT_LT(*rep.predicted_mse, 0.03 * 0.97);
  }
  EXPECT_TRUE(seen);
}

}  // namespace
}  // namespace ncosim::sim

namespace ncosim::sim {
namespace {

// The known issue of buffered packets, pinned: the jump observer's design model counts a sample
// re-sent in a later buffered packet as a new measurement with its own noise. Simulated with
// physical packets (the same noise every time) tr(Pt) is far above the prediction; simulated
// with resend_noise = "fresh" (a new draw per re-send, the design model) it agrees with it.
TEST(DolzFig5, BufferedPredictionHoldsWithFreshResendNoiseOnly) {
  for (const char* mode : {"same", "fresh"}) {
    auto sc = testing::load_one(
        testing::source_path("scenarios/dolz2014_fig5.toml"),
        {"sweep[0].values=[0.85]", fmt::format("sensor[0].resend_noise=\"{}\"", mode),
         "run.runs=20", "run.periods=5000"});
    CampaignOptions opt;
    opt.time_estimators = false;
    const auto rows = summarise(*sc, run_campaign(*sc, opt), {});
    for (const auto& row : rows) {
      if (row.estimator != "S4 N1 b3" && row.estimator != "S4 N4 b3") continue;
      ASSERT_TRUE(row.mse_ext && row.mse_ext_ci95 && row.predicted_mse_ext) << row.estimator;
      const double sim = *row.mse_ext, ci = *row.mse_ext_ci95, pred = *row.predicted_mse_ext;
      std::printf("resend_noise %-5s %s: predicted %.4f simulated %.4f ± %.4f\n", mode,
                  row.estimator.c_str(), pred, sim, ci);
      if (std::string(mode) == "fresh") {
        EXPECT_NEAR(sim, pred, 2.0 * ci) << row.estimator;
      } else {
        EXPECT_GT(sim, pred + 5.0 * ci) << row.estimator;
      }
    }
  }
}

}  // namespace
}  // namespace ncosim::sim
