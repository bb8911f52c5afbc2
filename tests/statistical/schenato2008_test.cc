// tests/statistical/schenato2008_test.cc — Monte Carlo properties of the buffered estimators of
// Schenato (2008) on the paper's examples (scenarios/schenato2008_*.toml, a subset of the
// buffer lengths), with bounds from the number of runs.
#include <gtest/gtest.h>

#include <algorithm>
#include <boost/math/distributions/students_t.hpp>
#include <cmath>
#include <cstdio>

#include "sim/analysis/output.h"
#include "sim/run/campaign.h"
#include "test_util.h"

namespace ncosim::sim {
namespace {

using testing::load_one;
using testing::source_path;

struct Stats {
  double mean = 0.0, se = 0.0;
  std::size_t n = 0;
};

Stats stats(const std::vector<double>& v) {
  Stats s;
  s.n = v.size();
  for (double x : v) s.mean += x;
  s.mean /= static_cast<double>(v.size());
  double ss = 0.0;
  for (double x : v) ss += (x - s.mean) * (x - s.mean);
  s.se = std::sqrt(ss / static_cast<double>(v.size() - 1) / static_cast<double>(v.size()));
  return s;
}

// Two-sided Student-t quantile at level 1 - alpha, n - 1 degrees of freedom.
double t_quantile(std::size_t n, double alpha) {
  return boost::math::quantile(
      boost::math::complement(boost::math::students_t(static_cast<double>(n - 1)), alpha / 2));
}

std::vector<double> per_run(const CampaignResult& r, std::size_t e) {
  std::vector<double> v;
  for (const auto& run : r.runs) v.push_back(run[e].sse / static_cast<double>(run[e].count));
  return v;
}

// Keeps only the named estimators of a loaded scenario (the committed files list N = 1..16).
void keep_only(Scenario& sc, const std::vector<std::string>& names) {
  std::erase_if(sc.estimators, [&](const EstimatorEntry& e) {
    return std::find(names.begin(), names.end(), e.name) == names.end();
  });
  ASSERT_EQ(sc.estimators.size(), names.size());
}

std::size_t index_of(const Scenario& sc, const std::string& name) {
  for (std::size_t i = 0; i < sc.estimators.size(); ++i) {
    if (sc.estimators[i].name == name) return i;
  }
  ADD_FAILURE() << "no estimator " << name;
  return 0;
}

// For every stable N with a finite fourth moment: the simulated mean |x - xhat|^2 of static_buffer
// inside the 95 % CI of predicted_mse (Bonferroni over the N checked: each at 95 %/m), and
// kalman_buffer not worse than static_buffer on the same runs beyond Monte Carlo error (paired).
// Rows with an infinite fourth moment say heavy_tail and are not compared.
void check_example(const std::string& file, const std::vector<int>& buffers, std::int64_t runs,
                   std::int64_t periods) {
  auto sc = load_one(source_path(file), {"run.runs=" + std::to_string(runs),
                                         "run.periods=" + std::to_string(periods)});
  std::vector<std::string> names;
  for (int N : buffers) {
    names.push_back(fmt::format("static N={}", N));
    names.push_back(fmt::format("optimal N={}", N));
  }
  keep_only(*sc, names);
  CampaignOptions opt;
  opt.time_estimators = false;
  const CampaignResult r = run_campaign(*sc, opt);
  const auto rows = summarise(*sc, r, {});
  const double alpha = 0.05 / static_cast<double>(buffers.size());
  for (int N : buffers) {
    const std::size_t s = index_of(*sc, fmt::format("static N={}", N));
    const std::size_t k = index_of(*sc, fmt::format("optimal N={}", N));
    const auto& rep = sc->estimators[s].design->report();
    SCOPED_TRACE(fmt::format("{} N={}", file, N));
    ASSERT_TRUE(rep.stable.value());
    const bool heavy = rep.extra["heavy_tail"].get<bool>();
    EXPECT_EQ(rows[s].status, heavy ? "heavy_tail" : "ok");
    const Stats st = stats(per_run(r, s));
    const double predicted = rep.predicted_mse.value();
    const double half = t_quantile(st.n, alpha) * st.se;
    std::printf("%s N=%d: static %.4f +- %.4f (predicted %.4f)%s\n", file.c_str(), N, st.mean, half,
                predicted, heavy ? " heavy_tail" : "");
    if (!heavy) {
      EXPECT_LT(std::abs(st.mean - predicted), half) << st.mean << " vs " << predicted;
    }
    std::vector<double> diff;
    const auto a = per_run(r, k), b = per_run(r, s);
    for (std::size_t i = 0; i < a.size(); ++i) diff.push_back(a[i] - b[i]);
    const Stats d = stats(diff);
    EXPECT_LT(d.mean, t_quantile(d.n, alpha) * d.se)
        << "kalman_buffer worse than static_buffer by " << d.mean;
  }
}

TEST(Schenato2008, StaticBufferMatchesItsPredictionAndKalmanBufferIsNoWorseMotor) {
  check_example("scenarios/schenato2008_motor.toml", {2, 4, 8, 16}, 24, 20000);
}

TEST(Schenato2008, StaticBufferMatchesItsPredictionAndKalmanBufferIsNoWorsePendulum) {
  check_example("scenarios/schenato2008_pendulum.toml", {9, 12, 16}, 24, 20000);
}

// The timing is pinned: every packet handed to the estimator one period after it arrived (the
// commonest timing bug) leaves the prediction by far; the correct timing stays inside it.
class LateByOne final : public est::Estimator {
 public:
  explicit LateByOne(std::unique_ptr<est::Estimator> inner) : inner_(std::move(inner)) {}
  int on_packet(const est::Packet& p, std::int64_t) override {
    next_.push_back(p);
    return 0;
  }
  void on_period(std::int64_t k, const est::PeriodInput& in) override {
    for (const auto& p : now_) inner_->on_packet(p, k);
    now_.swap(next_);
    next_.clear();
    inner_->on_period(k, in);
  }
  StateView state() const override { return inner_->state(); }

 private:
  std::unique_ptr<est::Estimator> inner_;
  std::vector<est::Packet> now_, next_;
};

class LateByOneDesign final : public est::EstimatorDesign {
 public:
  explicit LateByOneDesign(std::unique_ptr<est::EstimatorDesign> inner)
      : inner_(std::move(inner)) {}
  std::unique_ptr<est::Estimator> instantiate() const override {
    return std::make_unique<LateByOne>(inner_->instantiate());
  }
  const est::DesignReport& report() const override { return inner_->report(); }
  std::optional<double> flops_per_period() const override { return inner_->flops_per_period(); }

 private:
  std::unique_ptr<est::EstimatorDesign> inner_;
};

TEST(Schenato2008, FeedingPacketsOnePeriodLateLeavesThePrediction) {
  // Motor, N = 4: the correct estimator inside its CI, the late one (a second copy of the same
  // design) far outside: above the prediction by more than 5 CI half-widths and by 20 %.
  auto sc = load_one(source_path("scenarios/schenato2008_motor.toml"),
                     {"run.runs=24", "run.periods=20000"});
  keep_only(*sc, {"static N=4", "optimal N=4"});
  const std::size_t s = index_of(*sc, "static N=4");
  const std::size_t other = index_of(*sc, "optimal N=4");
  // Replace the kalman_buffer of N = 4 by a late-fed copy of the static design of N = 4.
  auto copy = load_one(source_path("scenarios/schenato2008_motor.toml"));
  sc->estimators[other].design = std::make_unique<LateByOneDesign>(
      std::move(copy->estimators[index_of(*copy, "static N=4")].design));
  CampaignOptions opt;
  opt.time_estimators = false;
  const CampaignResult r = run_campaign(*sc, opt);
  const double predicted = sc->estimators[s].design->report().predicted_mse.value();
  const Stats good = stats(per_run(r, s)), late = stats(per_run(r, other));
  const double half_good = t_quantile(good.n, 0.05) * good.se,
               half_late = t_quantile(late.n, 0.05) * late.se;
  std::printf(
      "motor N=4: predicted %.4f, correct timing %.4f +- %.4f, one period late %.4f +- %.4f\n",
      predicted, good.mean, half_good, late.mean, half_late);
  EXPECT_LT(std::abs(good.mean - predicted), half_good);
  EXPECT_GT(late.mean - predicted, 5 * half_late);
  EXPECT_GT(late.mean - predicted, 0.2 * predicted);
}

}  // namespace
}  // namespace ncosim::sim
