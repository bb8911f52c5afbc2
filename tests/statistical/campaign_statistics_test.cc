// tests/statistical/campaign_statistics_test.cc — Monte Carlo properties of whole campaigns,
// with bounds from the number of runs (Release only: too long under the sanitizers).
#include <gtest/gtest.h>

#include <boost/math/distributions/students_t.hpp>
#include <cmath>

#include "sim/analysis/output.h"
#include "sim/run/campaign.h"
#include "test_util.h"

namespace ncosim::sim {
namespace {

using testing::load_one;
using testing::source_path;

const std::string kTable2 = source_path("scenarios/dolz2014_table2.toml");

int index_of(const Scenario& sc, const std::string& name) {
  for (std::size_t i = 0; i < sc.estimators.size(); ++i) {
    if (sc.estimators[i].name == name) return static_cast<int>(i);
  }
  ADD_FAILURE() << "no estimator " << name;
  return 0;
}

std::vector<double> per_run(const CampaignResult& r, int e, bool ext) {
  std::vector<double> v;
  for (const auto& run : r.runs) {
    const auto& m = run[static_cast<std::size_t>(e)];
    v.push_back((ext ? m.sse_ext : m.sse) / static_cast<double>(m.count));
  }
  return v;
}

// Two-sided 99.9% Student-t quantile for n - 1 degrees of freedom.
double t999(std::size_t n) {
  return boost::math::quantile(
      boost::math::complement(boost::math::students_t(static_cast<double>(n - 1)), 0.0005));
}

TEST(CampaignStatistics, SimulatedS4MatchesItsPredictionUnderTheDesignModel) {
  // With independent copies per fictitious sensor (Dolz Remark 2.3) the simulation is the
  // design model, so the time-averaged |xbar - xhat|^2 of S4 (Nbar = 4) must equal tr(Pt) of
  // the corrected eq. (28) within Monte Carlo error: |mean - predicted| < t_0.999 * SE.
  auto sc = load_one(kTable2, {"link[0].independent=true", "link[1].independent=true",
                               "run.runs=24", "run.periods=40000"});
  CampaignOptions opt;
  opt.time_estimators = false;
  const CampaignResult r = run_campaign(*sc, opt);
  const int s4 = index_of(*sc, "S4, 60 gains");
  const auto v = per_run(r, s4, true);
  double mean = 0.0;
  for (double x : v) mean += x;
  mean /= static_cast<double>(v.size());
  double ss = 0.0;
  for (double x : v) ss += (x - mean) * (x - mean);
  const double se =
      std::sqrt(ss / static_cast<double>(v.size() - 1) / static_cast<double>(v.size()));
  const double half = t999(v.size()) * se;
  const double predicted =
      sc->estimators[static_cast<std::size_t>(s4)].design->report().predicted_mse_ext.value();
  std::printf("S4 simulated %.5f, predicted %.5f, 99.9%% half-width %.5f\n", mean, predicted, half);
  EXPECT_LT(std::abs(mean - predicted), half);
  EXPECT_LT(half, 0.05 * predicted) << "the test must be sharp: the interval is wider than 5%";
}

TEST(CampaignStatistics, KalmanIsNeverWorseAndOpenLoopNeverBetterOnTheSameRealisation) {
  // Paired per run (common random numbers): for every jump observer J,
  // mean(mse_J - mse_KF) > -t_0.999 SE, and open loop is worse than every other estimator.
  auto sc = load_one(kTable2,
                     {"run.runs=12", "run.periods=20000", "run.recentre=\"never\"",
                      "plant.A=[[0.8821, -0.0351], [-0.0351, 0.7347]]"});  // A1: open loop finite
  CampaignOptions opt;
  opt.time_estimators = false;
  const CampaignResult r = run_campaign(*sc, opt);
  const int kf = index_of(*sc, "Kalman");
  const int ol = index_of(*sc, "open loop");
  const auto kf_mse = per_run(r, kf, true);
  const auto ol_mse = per_run(r, ol, true);
  for (std::size_t e = 0; e < sc->estimators.size(); ++e) {
    if (static_cast<int>(e) == kf || static_cast<int>(e) == ol) continue;
    const auto v = per_run(r, static_cast<int>(e), true);
    std::vector<double> d;
    double mean = 0.0;
    for (std::size_t i = 0; i < v.size(); ++i) {
      d.push_back(v[i] - kf_mse[i]);
      mean += d.back();
    }
    mean /= static_cast<double>(d.size());
    double ss = 0.0;
    for (double x : d) ss += (x - mean) * (x - mean);
    const double se =
        std::sqrt(ss / static_cast<double>(d.size() - 1) / static_cast<double>(d.size()));
    EXPECT_GT(mean, -t999(d.size()) * se) << sc->estimators[e].name << " beats the Kalman filter";
    for (std::size_t i = 0; i < v.size(); ++i) {
      EXPECT_LT(v[i], ol_mse[i]) << sc->estimators[e].name << " is worse than open loop in run "
                                 << i;
    }
  }
}

}  // namespace
}  // namespace ncosim::sim
