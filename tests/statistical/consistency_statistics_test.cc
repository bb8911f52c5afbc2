// tests/statistical/consistency_statistics_test.cc — the error curve against the Kalman
// filter's covariance recursion, and the NEES/NIS consistency check on a correctly tuned and a
// mistuned filter (fixed seeds; bounds from the number of runs).
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <boost/math/distributions/normal.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "sim/analysis/output.h"
#include "sim/run/campaign.h"
#include "test_util.h"

namespace ncosim::sim {
namespace {

using testing::load_one;

// Two states, two sensors; every packet delivered in its period (bernoulli, loss 0, delay 0).
// The estimate starts exact (xhat0 = x0, P0 = 0), so E[e e'] = P[k|k] of the Kalman recursion.
const char* kPlant = R"(
[plant]
kind = "lti"
A  = [[0.95, 0.2], [-0.1, 0.9]]
Bw = [[1.0, 0.0], [0.0, 1.0]]
W  = [[0.1, 0.02], [0.02, 0.05]]
x0 = [1.0, -1.0]

[input]
kind = "none"

[[sensor]]
name = "y1"
C = [[1.0, 0.0]]
R = [[0.2]]
link = "l1"

[[sensor]]
name = "y2"
C = [[0.5, 1.0]]
R = [[0.3]]
link = "l2"
)";

// Sensor 1's link loses `loss` of its packets, sensor 2's none; no delay.
std::string links(double loss) {
  return fmt::format(
      "\n[[link]]\nname = \"l1\"\nkind = \"bernoulli\"\nloss = {}\n\n"
      "[[link]]\nname = \"l2\"\nkind = \"bernoulli\"\nloss = 0.0\n",
      loss);
}

std::string write_scenario(const std::string& name, const std::string& text) {
  const auto dir = std::filesystem::temp_directory_path() / "ncosim_consistency_test";
  std::filesystem::create_directories(dir);
  const auto path = dir / name;
  std::ofstream(path) << text;
  return path.string();
}

// P[k|k] from P[0|-] = 0: predict (k > 0) then update with both rows.
std::vector<double> kalman_traces(int periods) {
  Eigen::Matrix2d A, Q, R, P = Eigen::Matrix2d::Zero();
  A << 0.95, 0.2, -0.1, 0.9;
  Q << 0.1, 0.02, 0.02, 0.05;
  R << 0.2, 0.0, 0.0, 0.3;
  Eigen::Matrix2d C;
  C << 1.0, 0.0, 0.5, 1.0;
  std::vector<double> tr;
  for (int k = 0; k < periods; ++k) {
    if (k > 0) P = A * P * A.transpose() + Q;
    const Eigen::Matrix2d S = C * P * C.transpose() + R;
    const Eigen::Matrix2d K = P * C.transpose() * S.inverse();
    P = P - K * C * P;
    tr.push_back(P.trace());
  }
  return tr;
}

TEST(ErrorCurveStatistics, FollowsTheKalmanCovarianceRecursionFromAnExactStart) {
  constexpr int kPeriods = 40;
  const std::string file = write_scenario("curve.toml", std::string(R"(
[run]
periods = 40
warmup = 1
runs = 3000
seed = 11
error_curve = true
)") + kPlant + links(0.0) + R"(
[[estimator]]
name = "Kalman"
kind = "kalman_extended"
)");
  auto sc = load_one(file);
  CampaignOptions opt;
  opt.time_estimators = false;
  const CampaignResult r = run_campaign(*sc, opt);
  ASSERT_EQ(r.curve.runs().size(), 3000U);
  const auto tr = kalman_traces(kPeriods);
  // Each period's mean is an average of 3000 independent runs: within 4.5 standard errors of
  // E|e|^2 = tr P[k|k] (a false alarm in one of 40 periods: < 3e-4). The start is exact
  // (tr P[0|0] = 0) and the transient grows to the stationary value over ~10 periods, so an
  // off-by-one period or a missing update would be caught far outside these bounds.
  const double z = 4.5 / boost::math::quantile(boost::math::normal(), 0.975);
  EXPECT_EQ(r.curve.mean(0, 0), 0.0);
  for (int k = 1; k < kPeriods; ++k) {
    const double half = z * r.curve.ci95(k, 0);
    EXPECT_NEAR(r.curve.mean(k, 0), tr[static_cast<std::size_t>(k)], half) << "period " << k;
    EXPECT_LT(half, 0.12 * tr[static_cast<std::size_t>(k)])
        << "the band is too wide to test anything";
  }
  EXPECT_GT(tr[10], 1.5 * tr[1]);  // the transient is visible
}

// The summary rows of a campaign with a tuned Kalman filter and a sod_kalman (periodic sensors:
// the Kalman filter with intermittent observations) whose process-noise covariance is the
// plant's W times `w_scale`.
std::vector<SummaryRow> filter_rows(const std::string& name, double w_scale) {
  const auto w = [&](double v) { return fmt::format("{}", v * w_scale); };
  const std::string text = std::string(R"(
[run]
periods = 3000
warmup = 100
runs = 30
seed = 12
)") + kPlant + links(0.3) + R"(
[[estimator]]
name = "Kalman"
kind = "kalman_extended"

[[estimator]]
name = "KF with its own W"
kind = "sod_kalman"
)" + fmt::format("W = [[{}, {}], [{}, {}]]\n", w(0.1), w(0.02), w(0.02), w(0.05));
  auto sc = load_one(write_scenario(name, text));
  CampaignOptions opt;
  opt.time_estimators = false;
  return summarise(*sc, run_campaign(*sc, opt), {});
}

TEST(ConsistencyStatistics, ATunedKalmanFilterIsConsistentAndOneWithQTimesPointOneIsFlagged) {
  // Sensor 1 loses 30 % of its packets, so P is time-varying. Both filters of the first campaign
  // know the plant exactly: their NEES (n = 2) and NIS must lie within the 95 % bounds.
  const auto tuned = filter_rows("tuned.toml", 1.0);
  for (const auto& r : tuned) {
    ASSERT_TRUE(r.nees.has_value()) << r.estimator;
    ASSERT_TRUE(r.nis.has_value()) << r.estimator;
    EXPECT_EQ(r.consistency, "ok")
        << r.estimator << ": nees " << r.nees->mean << " in [" << r.nees->lo << ", " << r.nees->hi
        << "], nis " << r.nis->mean << " in [" << r.nis->lo << ", " << r.nis->hi << "]";
    EXPECT_NEAR(r.nees->mean, 2.0, 0.1) << r.estimator;
    // One update of 1 or 2 rows per period: the expected NIS is the mean rows per update (1.7).
    EXPECT_NEAR(r.nis->mean, 1.7, 0.1) << r.estimator;
  }
  // The same filter believing Q is a tenth of the truth: its covariance is too small.
  const auto mistuned = filter_rows("mistuned.toml", 0.1);
  EXPECT_EQ(mistuned[0].consistency, "ok");
  const SummaryRow& bad = mistuned[1];
  ASSERT_TRUE(bad.nees.has_value());
  EXPECT_GT(bad.nees->mean, bad.nees->hi);
  EXPECT_NE(bad.consistency.find("NEES above its 95 % bound"), std::string::npos)
      << bad.consistency;
  EXPECT_NE(bad.consistency.find("NIS above its 95 % bound"), std::string::npos) << bad.consistency;
  // Estimators without a covariance have no statistic.
}

}  // namespace
}  // namespace ncosim::sim
