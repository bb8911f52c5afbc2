// tests/statistical/paired_statistics_test.cc — the paired columns of summary.csv
// (sim/analysis/paired.h): coverage of the paired CI at its nominal rate on a scenario with a known
// difference, and the gain over the unpaired interval on the flagship.
#include <gtest/gtest.h>

#include <boost/math/distributions/binomial.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "sim/analysis/output.h"
#include "sim/analysis/paired.h"
#include "sim/run/campaign.h"
#include "test_util.h"

namespace ncosim::sim {
namespace {

using testing::source_path;

// Scalar plant x[k] = 0.8 x[k-1] + w, W = 1, one sensor y = x + v, R = 1, ideal link; the
// Kalman filter (P0 = 0, x0 known) and open loop. Expected per-run MSEs follow from the error
// covariance recursions: open loop S[k] = 0.64 S[k-1] + 1, the filter P-[k] = 0.64 P[k-1] + 1,
// P[k] = P-[k] R / (P-[k] + R), both from 0 at k = 0 (the sample at k = 0 is exact: e = 0).
constexpr const char* kScalar = R"(title = "paired coverage"
[run]
periods = 300
warmup = 50
runs = 10
seed = 1
[plant]
kind = "lti"
A = [[0.8]]
W = [[1.0]]
[[sensor]]
name = "y"
C = [[1.0]]
R = [[1.0]]
[[estimator]]
name = "kf"
kind = "kalman_extended"
[[estimator]]
name = "ol"
kind = "open_loop"
)";

std::string write_temp(const std::string& name, const std::string& text) {
  const auto p = std::filesystem::temp_directory_path() / name;
  std::ofstream(p) << text;
  return p.string();
}

// [lo, hi]: the central 99.9 % range of the number of misses of a 95 % interval in `reps` trials.
std::pair<double, double> miss_range(int reps) {
  const boost::math::binomial_distribution<> b(reps, 0.05);
  return {boost::math::quantile(b, 0.0005),
          boost::math::quantile(boost::math::complement(b, 0.0005))};
}

TEST(PairedStatistics, PairedIntervalCoversTheKnownDifferenceAtItsNominalRate) {
  // Work out the truth: mean over k in [50, 300) of S[k] - P[k] (open loop minus filter) and
  // of S[k] / mean P[k] for the ratio of means.
  double s = 0.0, p = 0.0, sum_s = 0.0, sum_p = 0.0;
  for (int k = 1; k < 300; ++k) {
    s = 0.64 * s + 1.0;
    const double pm = 0.64 * p + 1.0;
    p = pm / (pm + 1.0);
    if (k >= 50) {
      sum_s += s;
      sum_p += p;
    }
  }
  const double true_diff = (sum_s - sum_p) / 250.0;
  const double true_ratio = sum_s / sum_p;
  const std::string file = write_temp("ncosim_paired_coverage.toml", kScalar);
  auto sc = testing::load_one(file);
  std::filesystem::remove(file);
  CampaignOptions opt;
  opt.time_estimators = false;
  opt.threads = 2;
  const int reps = 400;
  int miss_diff = 0, miss_ratio = 0;
  double width_paired = 0.0, width_welch = 0.0;
  for (int rep = 0; rep < reps; ++rep) {
    sc->run.seed = 1000 + static_cast<std::uint64_t>(rep);
    const CampaignResult r = run_campaign(*sc, opt);
    const auto rows = summarise(*sc, r, {});
    ASSERT_EQ(rows[1].paired.reference, "kf");  // default: the first Kalman-type row
    const PairedMetric& m = rows[1].paired.mse;
    ASSERT_TRUE(m.diff && m.diff_ci95 && m.ratio && m.ratio_ci95);
    if (std::abs(*m.diff - true_diff) > *m.diff_ci95) ++miss_diff;
    if (std::abs(*m.ratio - true_ratio) > *m.ratio_ci95) ++miss_ratio;
    width_paired += *m.diff_ci95;
    width_welch += welch_difference(rows[0].per_run.mse, rows[1].per_run.mse)->diff_half.value();
  }
  const auto [lo, hi] = miss_range(reps);
  std::printf(
      "true difference %.5f, ratio %.5f; misses of the 95%% CI in %d repetitions: difference %d, "
      "ratio %d (99.9%% binomial range [%g, %g]); mean half-width paired %.4f, Welch %.4f\n",
      true_diff, true_ratio, reps, miss_diff, miss_ratio, lo, hi, width_paired / reps,
      width_welch / reps);
  EXPECT_GE(miss_diff, lo);
  EXPECT_LE(miss_diff, hi);
  EXPECT_GE(miss_ratio, lo);
  EXPECT_LE(miss_ratio, hi);
}

TEST(PairedStatistics, FlagshipPairedIntervalOfS4VsKalmanIsNarrowerThanTheUnpairedOne) {
  // Table 2 as committed (20 runs x 20000 periods, seed 2014): the S4 row's paired half-width
  // against the Kalman filter (the default reference) and the Welch half-width of the same two
  // sets of per-run values treated as independent. Measured: 4.7x (mse), 4.5x (mse_ext). The
  // gain is sqrt((s_a^2 + s_b^2) / s_d^2) up to the t quantiles: it depends on the correlation of
  // the two rows' per-run errors, and over 40 seeds it spans 2.5x..8.3x for this pair (median
  // 3.9x; tests/statistical/compare_statistics_test.cc), so the issue's 5x is not a property
  // of S4 vs Kalman on the flagship; closer rows (S4 history 3 vs 4) gain >= 5x at every seed
  // (that test). Here: the committed flagship gains at least 4x.
  auto sc = testing::load_one(source_path("scenarios/dolz2014_table2.toml"));
  CampaignOptions opt;
  opt.time_estimators = false;
  opt.threads = 2;
  const CampaignResult r = run_campaign(*sc, opt);
  const auto rows = summarise(*sc, r, {});
  const SummaryRow* s4 = nullptr;
  const SummaryRow* kf = nullptr;
  for (const auto& row : rows) {
    if (row.estimator == "S4, 60 gains") s4 = &row;
    if (row.estimator == "Kalman") kf = &row;
  }
  ASSERT_TRUE(s4 && kf);
  EXPECT_EQ(s4->paired.reference, "Kalman");
  for (const bool ext : {false, true}) {
    const PairedMetric& m = ext ? s4->paired.mse_ext : s4->paired.mse;
    const auto& a = ext ? kf->per_run.mse_ext : kf->per_run.mse;
    const auto& b = ext ? s4->per_run.mse_ext : s4->per_run.mse;
    const auto welch = welch_difference(a, b);
    ASSERT_TRUE(m.diff_ci95 && welch && welch->diff_half);
    const double factor = *welch->diff_half / *m.diff_ci95;
    std::printf(
        "%s: S4 - Kalman = %.6f, paired half-width %.3g, unpaired (Welch) %.3g: %.1fx narrower\n",
        ext ? "mse_ext" : "mse", *m.diff, *m.diff_ci95, *welch->diff_half, factor);
    EXPECT_NEAR(*m.diff, welch->diff, 1e-12);  // the same estimate, only the interval differs
    EXPECT_GE(factor, 4.0);
  }
  // Physical packets: the prediction (0.056) is not compared with the simulation (0.045).
  EXPECT_EQ(s4->model_check.rfind("design model not followed (physical packets", 0), 0u)
      << s4->model_check;
}

TEST(PairedStatistics, ModelCheckFindsS4ConsistentWithItsPredictionUnderIndependentCopies) {
  // Independent copies per delay (Dolz Remark 2.3) realise the design model: the simulated
  // mse_ext of S4 must lie within the 99.9 % Monte Carlo error of tr(Pt).
  auto sc = testing::load_one(source_path("scenarios/dolz2014_table2.toml"),
                              {"link[0].independent=true", "link[1].independent=true"});
  CampaignOptions opt;
  opt.time_estimators = false;
  opt.threads = 2;
  const auto rows = summarise(*sc, run_campaign(*sc, opt), {});
  std::printf("%s\n", rows[4].model_check.c_str());
  EXPECT_EQ(rows[4].model_check.rfind("consistent: simulated mse_ext", 0), 0u)
      << rows[4].model_check;
}

}  // namespace
}  // namespace ncosim::sim
