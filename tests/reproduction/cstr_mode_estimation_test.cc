// tests/reproduction/cstr_mode_estimation_test.cc — Moayedi et al., CSTR example, Table 2:
// our committed 2000-run values (results/cstr_mode_estimation/) re-estimated from 400 fresh runs
// (another seed), and where the paper's numbers stand against them.
#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "sim/analysis/output.h"
#include "sim/run/campaign.h"
#include "test_util.h"

namespace ncosim::sim {
namespace {

struct Values {
  double mde, rmse1, rmse2;           // ours: mean over 2000 runs (seed 2013)
  double sd_mde, sd_rmse1, sd_rmse2;  // run-to-run standard deviations of those runs
  double paper_mde, paper_rmse1, paper_rmse2;
};

// results/cstr_mode_estimation/summary.csv (mde_percent, ermse_x1, ermse_x2) and the per-run
// standard deviations from its runs.csv; the paper's Table 2.
const std::map<std::string, Values> kOurs{
    {"Algorithm 1", {9.7575, 0.0947812, 19.6512, 13.6, 0.1374, 30.0, 6.9, 0.11, 4.3}},
    {"Algorithm 2", {39.316, 0.264334, 59.2411, 37.98, 0.2593, 58.51, 13.1, 0.15, 13.2}},
    {"IMM", {6.4125, 0.0147551, 1.87162, 9.445, 0.05844, 13.5, 8.2, 0.006, 0.53}},
};

// The mean of R = 400 independent runs differs from the 2000-run mean by a normal variable of
// sd s sqrt(1/400 + 1/2000) (CLT; s the run-to-run sd), so 4.5 of those is a bound that a
// correct build fails with probability < 1e-5 per quantity.
TEST(CstrTable2, FreshRunsAgreeWithTheCommittedReproduction) {
  auto sc = testing::load_one(testing::source_path("scenarios/cstr_mode_estimation.toml"),
                              {"run.runs=400", "run.seed=7"});
  CampaignOptions opt;
  opt.time_estimators = false;
  const auto rows = summarise(*sc, run_campaign(*sc, opt), {});
  ASSERT_EQ(rows.size(), 3U);
  const double f = 4.5 * std::sqrt(1.0 / 400 + 1.0 / 2000);
  for (const auto& r : rows) {
    SCOPED_TRACE(r.estimator);
    const Values& v = kOurs.at(r.estimator);
    ASSERT_TRUE(r.mde_percent && r.ermse[0] && r.ermse[1]);
    EXPECT_NEAR(*r.mde_percent, v.mde, f * v.sd_mde);
    EXPECT_NEAR(*r.ermse[0], v.rmse1, f * v.sd_rmse1);
    EXPECT_NEAR(*r.ermse[1], v.rmse2, f * v.sd_rmse2);
    std::printf("%-12s MDE %.3g %% (paper %.3g)  E{RMSE1} %.3g (%.3g)  E{RMSE2} %.3g (%.3g)\n",
                r.estimator.c_str(), *r.mde_percent, v.paper_mde, *r.ermse[0], v.paper_rmse1,
                *r.ermse[1], v.paper_rmse2);
  }
}

// Where we stand against Table 2 (results/README.md explains why): the 95 % CI half-width of a
// 2000-run mean is 1.96 s / sqrt(2000). The IMM's MDE and Algorithm 1's E{RMSE1} are within
// reach of the paper; Algorithm 2's MDE is far above the paper's 13.1 % (more than 10 CI
// half-widths), and so is Algorithm 1's E{RMSE2}.
TEST(CstrTable2, WhereOurValuesStandAgainstThePaper) {
  const double ci = 1.96 / std::sqrt(2000.0);
  const Values& a1 = kOurs.at("Algorithm 1");
  const Values& a2 = kOurs.at("Algorithm 2");
  const Values& imm = kOurs.at("IMM");
  EXPECT_GT(a2.mde - a2.paper_mde, 10 * ci * a2.sd_mde);
  EXPECT_GT(a1.rmse2 - a1.paper_rmse2, 10 * ci * a1.sd_rmse2);
  EXPECT_LT(std::abs(a1.rmse1 - a1.paper_rmse1), 4 * ci * a1.sd_rmse1);
  EXPECT_LT(std::abs(imm.mde - imm.paper_mde), 5 * ci * imm.sd_mde);
  // The ordering the paper reports for the state: the IMM best, Algorithm 2 worst.
  EXPECT_LT(imm.rmse1, a1.rmse1);
  EXPECT_LT(a1.rmse1, a2.rmse1);
}

}  // namespace
}  // namespace ncosim::sim
