// tests/statistical/overload_statistics_test.cc — the overload test's false alarms on bursty
// stationary links and the error-growth note's, from whole campaigns at fixed seeds
// (sim/run/trend.h, sim/run/overload.h; results/README.md, "Overload and growth").
//
// One campaign of N x R runs is cut into N campaigns of R runs (the runs are independent: each
// has its own random streams). The links are stationary from their first packet (a Markov chain
// starts from its stationary law), so every trend test's null holds and its p-value is uniform, or
// larger where the test is conservative: the count of p < a over the N campaigns is at most
// Binomial(N, a), whose 0.999 quantile bounds it. The naive test (least squares on the block means
// taken as independent points, combined over the runs) is run on the same campaigns: it must
// false-alarm beyond that bound, or the links would not be bursty enough to tell the tests apart.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <boost/math/distributions/binomial.hpp>
#include <boost/math/distributions/normal.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "sim/run/campaign.h"
#include "sim/run/link_report.h"
#include "sim/run/overload.h"
#include "sim/scenario/scenario.h"

namespace ncosim::sim {
namespace {

constexpr std::size_t kCampaigns = 400;

// A scalar plant, one sensor sending every period over `link`, a Kalman filter whose error follows
// the link's bursts (it needs max_delay >= the link's delays) and an open-loop predictor.
std::string scenario(const std::string& link, int periods, std::size_t runs) {
  return fmt::format(R"(title = "stationary bursty link"
[run]
periods = {}
warmup = 50
runs = {}
seed = 2024
[plant]
kind = "lti"
A = [[0.95]]
Bw = [[1.0]]
W = [[1.0]]
[[sensor]]
name = "s"
C = [[1.0]]
R = [[0.5]]
link = "l"
[[link]]
name = "l"
{}
[[estimator]]
name = "Kalman"
kind = "kalman_extended"
max_delay = 4
[[estimator]]
name = "open loop"
kind = "open_loop"
)",
                     periods, runs, link);
}

// A Markov link whose good state (mean stay 500 periods) loses 5 % with delays 0-1 and whose bad
// one (mean stay 100) loses 60 % with delays 1-3: its correlation time, 1 / (1 - 0.988) = 83
// periods, is that of the blocks (47 to 94 packets); and a Gilbert–Elliott link losing 30 % in
// bursts of 100 on average (correlation time 1 / (0.01 + 0.0043) = 70 periods).
const char* const kMarkov = R"(kind = "markov"
transition = [[0.998, 0.002], [0.01, 0.99]]
loss = [0.05, 0.6]
delay_pmf = [[0.8, 0.2], [0.0, 0.2, 0.4, 0.4]]
step = "period")";
// The same chain 10 times faster (correlation time 8 periods): it forgets its state well within
// an eighth of a run, the assumption of the test with fewer than 5 runs.
const char* const kMarkovFast = R"(kind = "markov"
transition = [[0.98, 0.02], [0.1, 0.9]]
loss = [0.05, 0.6]
delay_pmf = [[0.8, 0.2], [0.0, 0.2, 0.4, 0.4]]
step = "period")";
// Independent losses (Bernoulli, 20 %) and independent delays (negative binomial, mean 2): the
// textbook case, where the block means are independent too.
const char* const kBernoulli = R"(kind = "negative_binomial"
successes = 2
p = 0.5
loss = 0.2)";
const char* const kGilbert = R"(kind = "gilbert_elliott"
mean_loss = 0.3
mean_burst = 100.0
step = "period")";

struct Loaded {
  std::unique_ptr<LoadedScenario> loaded;
  const Scenario& sc() const { return *loaded->cases.front().scenario; }
};

Loaded load(const std::string& text) {
  const auto dir =
      std::filesystem::temp_directory_path() / fmt::format("ncosim_overload_{}", ::getpid());
  std::filesystem::create_directories(dir);
  const auto file = dir / "s.toml";
  std::ofstream(file) << text;
  Loaded l;
  l.loaded = std::make_unique<LoadedScenario>(load_cases(file.string(), {}));
  std::filesystem::remove_all(dir);
  return l;
}

// The campaign of n x r runs, cut in n campaigns of r runs.
std::vector<CampaignResult> campaigns(const Scenario& sc, std::size_t n, std::size_t r) {
  CampaignOptions o;
  o.time_estimators = false;
  o.threads = 2;
  CampaignResult all = run_campaign(sc, o);
  EXPECT_EQ(all.runs.size(), n * r);
  std::vector<CampaignResult> out(n);
  for (std::size_t i = 0; i < n * r && i < all.runs.size(); ++i) {
    out[i / r].runs.push_back(std::move(all.runs[i]));
    out[i / r].link_runs.push_back(std::move(all.link_runs[i]));
  }
  return out;
}

// The naive test: each run's block means taken as independent points about its least-squares
// line, the runs' slopes combined with weights 1 / their variances; one-sided p of growth.
double naive_p(const std::vector<BlockSeries>& runs) {
  double num = 0.0, den = 0.0;
  for (const BlockSeries& s : runs) {
    const auto l = fit_line(s);
    if (!l || s.y.size() < 4) continue;
    double tm = 0.0;
    for (const double t : s.t) tm += t;
    tm /= static_cast<double>(s.t.size());
    double stt = 0.0, rss = 0.0;
    for (std::size_t i = 0; i < s.t.size(); ++i) {
      stt += (s.t[i] - tm) * (s.t[i] - tm);
      const double e = s.y[i] - l->a - l->b * s.t[i];
      rss += e * e;
    }
    const double var = rss / static_cast<double>(s.y.size() - 2) / stt;
    if (!(var > 0.0)) continue;
    num += l->b / var;
    den += 1.0 / var;
  }
  if (!(den > 0.0)) return 1.0;
  const double z = num / std::sqrt(den);
  return boost::math::cdf(boost::math::complement(boost::math::normal(), z));
}

// The delay and loss series of flow 0 in each run of `res` (as flow_loads builds them).
std::pair<std::vector<BlockSeries>, std::vector<BlockSeries>> series_of(const CampaignResult& res) {
  std::vector<BlockSeries> delay, loss;
  for (const auto& run : res.link_runs) {
    const models::LinkCounters& c = run.at(0);
    BlockSeries d, l;
    const auto size = static_cast<double>(c.blocks.size);
    for (std::size_t i = 0; i < c.blocks.delivered.size(); ++i) {
      const double t = (static_cast<double>(i) + 0.5) * size / static_cast<double>(c.sent);
      l.t.push_back(t);
      l.y.push_back(1.0 - static_cast<double>(c.blocks.delivered[i]) / size);
      if (c.blocks.delivered[i] == 0) continue;
      d.t.push_back(t);
      d.y.push_back(static_cast<double>(c.blocks.delay[i]) /
                    static_cast<double>(c.blocks.delivered[i]));
    }
    delay.push_back(std::move(d));
    loss.push_back(std::move(l));
  }
  return {delay, loss};
}

// Per test: campaigns tested, with p < a, with the naive test's p < a, and told (for delay: the
// row's verdict is not `none`, by its delay or its loss test).
struct Counts {
  std::size_t tested = 0, below = 0, naive = 0, told = 0;
  void add(const std::optional<TrendResult>& t, double naive_p_value, bool is_told, double a) {
    if (!t) return;
    ++tested;
    below += t->p < a;
    naive += naive_p_value < a;
    told += is_told;
  }
};

// The Clopper–Pearson 95 % interval of k successes in n trials.
std::string clopper_pearson(std::size_t k, std::size_t n) {
  using B = boost::math::binomial;
  const auto kd = static_cast<double>(k), nd = static_cast<double>(n);
  return fmt::format("[{:.3g}, {:.3g}]",
                     B::find_lower_bound_on_p(nd, kd, 0.025, B::clopper_pearson_exact_interval),
                     B::find_upper_bound_on_p(nd, kd, 0.025, B::clopper_pearson_exact_interval));
}

// The 0.999 quantile of Binomial(n, a).
double bound(std::size_t n, double a) {
  return boost::math::quantile(boost::math::binomial(static_cast<double>(n), a), 0.999);
}

struct Rates {
  Counts delay, loss, error;
};

// The N campaigns of R runs of `link`: per test, the campaigns tested, with p < a, with the naive
// p < a, and told (links.csv `overload` not "none", an error-growth note).
Rates false_alarms(const char* link, std::size_t runs, int periods, double a) {
  const Loaded l = load(scenario(link, periods, kCampaigns * runs));
  Rates out;
  for (const CampaignResult& res : campaigns(l.sc(), kCampaigns, runs)) {
    const auto flows = link_flows(l.sc());
    const FlowLoad load = flow_loads(l.sc(), res, flows).at(0);
    const auto [delay, loss] = series_of(res);
    out.delay.add(load.delay, naive_p(delay), load.verdict != "none", a);
    out.loss.add(load.loss, naive_p(loss), false, a);
    const auto e = error_trend(res, 0);
    out.error.add(e, 1.0, e && error_grows(*e), a);
    EXPECT_NE(load.verdict, "overloaded");  // not a network link: never a failure
  }
  return out;
}

void report(const char* what, const Counts& c, double a, bool naive = true) {
  const std::string msg = fmt::format(
      "{}: {} campaigns tested; p < {:g} in {} {}{}, bound {:g}; told (level {:g} and material "
      "growth) {} {}",
      what, c.tested, a, c.below, clopper_pearson(c.below, c.tested),
      naive ? fmt::format(" (naive test: {})", c.naive) : "", bound(c.tested, a), kTrendAlpha,
      c.told, clopper_pearson(c.told, c.tested));
  ::testing::Test::RecordProperty(what, msg);
  std::cout << msg << "\n";
}

constexpr double kLevel = 0.05;

TEST(OverloadStatistics, MarkovLinkFalseAlarmsAcrossRuns) {
  const Rates r = false_alarms(kMarkov, 10, 3000, kLevel);
  report("markov delay, 10 runs", r.delay, kLevel);
  report("markov loss, 10 runs", r.loss, kLevel);
  report("markov Kalman error, 10 runs", r.error, kLevel, false);
  ASSERT_EQ(r.delay.tested, kCampaigns);
  ASSERT_EQ(r.loss.tested, kCampaigns);
  ASSERT_EQ(r.error.tested, kCampaigns);
  EXPECT_LE(r.delay.below, bound(kCampaigns, kLevel));
  EXPECT_LE(r.loss.below, bound(kCampaigns, kLevel));
  EXPECT_LE(r.error.below, bound(kCampaigns, kLevel));
  // The chain's bursts make the naive test false-alarm far beyond its level.
  EXPECT_GT(r.delay.naive, bound(kCampaigns, kLevel));
  EXPECT_GT(r.loss.naive, bound(kCampaigns, kLevel));
  // At the level used (two tests per flow), with the material-growth rule on top.
  EXPECT_LE(r.delay.told, bound(kCampaigns, 2 * kTrendAlpha));
  EXPECT_LE(r.error.told, bound(kCampaigns, kTrendAlpha));
}

TEST(OverloadStatistics, GilbertElliottLinkFalseAlarmsAcrossRuns) {
  const Rates r = false_alarms(kGilbert, 10, 3000, kLevel);
  report("gilbert_elliott delay (0: untold), 10 runs", r.delay, kLevel);
  report("gilbert_elliott loss, 10 runs", r.loss, kLevel);
  report("gilbert_elliott Kalman error, 10 runs", r.error, kLevel, false);
  ASSERT_EQ(r.loss.tested, kCampaigns);
  EXPECT_LE(r.loss.below, bound(kCampaigns, kLevel));
  EXPECT_LE(r.error.below, bound(kCampaigns, kLevel));
  EXPECT_GT(r.loss.naive, bound(kCampaigns, kLevel));
  EXPECT_LE(r.delay.told, bound(kCampaigns, 2 * kTrendAlpha));
  EXPECT_LE(r.error.told, bound(kCampaigns, kTrendAlpha));
}

TEST(OverloadStatistics, BernoulliLinkFalseAlarmsAcrossAndWithinRuns) {
  for (const std::size_t runs : {10u, 1u}) {
    const Rates r = false_alarms(kBernoulli, runs, 3000, kLevel);
    const std::string n = fmt::format("bernoulli, {} run(s)", runs);
    report((n + ", delay").c_str(), r.delay, kLevel);
    report((n + ", loss").c_str(), r.loss, kLevel);
    report((n + ", Kalman error").c_str(), r.error, kLevel, false);
    ASSERT_EQ(r.delay.tested, kCampaigns) << n;
    EXPECT_LE(r.delay.below, bound(kCampaigns, kLevel)) << n;
    EXPECT_LE(r.loss.below, bound(kCampaigns, kLevel)) << n;
    EXPECT_LE(r.error.below, bound(kCampaigns, kLevel)) << n;
    EXPECT_LE(r.delay.told, bound(kCampaigns, 2 * kTrendAlpha)) << n;
    EXPECT_LE(r.error.told, bound(kCampaigns, kTrendAlpha)) << n;
  }
}

// Fewer than 5 runs: Mann–Kendall on each run's 8 batch means, summed over the runs. Where its
// assumption holds (the fast chain) it keeps its level; on the slow chain, whose correlation time
// is a fifth of a batch, it is liberal at 5 % (measured, results/README.md), and the rule that
// tells a growth (0.001 and a material growth) must still keep its level.
TEST(OverloadStatistics, MarkovLinkFalseAlarmsWithinFewRuns) {
  for (const std::size_t runs : {1u, 3u}) {
    for (const bool fast : {true, false}) {
      const Rates r = false_alarms(fast ? kMarkovFast : kMarkov, runs, 3000, kLevel);
      const std::string n = fmt::format("{} markov, {} run(s)", fast ? "fast" : "slow", runs);
      report((n + ", delay").c_str(), r.delay, kLevel);
      report((n + ", loss").c_str(), r.loss, kLevel);
      report((n + ", Kalman error").c_str(), r.error, kLevel, false);
      if (fast) {
        EXPECT_LE(r.delay.below, bound(r.delay.tested, kLevel)) << n;
        EXPECT_LE(r.loss.below, bound(r.loss.tested, kLevel)) << n;
        EXPECT_LE(r.error.below, bound(r.error.tested, kLevel)) << n;
      } else {
        EXPECT_GT(r.delay.naive, bound(kCampaigns, kLevel)) << n;
      }
      EXPECT_LE(r.delay.told, bound(kCampaigns, 2 * kTrendAlpha)) << n;
      EXPECT_LE(r.error.told, bound(kCampaigns, kTrendAlpha)) << n;
    }
  }
}

}  // namespace
}  // namespace ncosim::sim
