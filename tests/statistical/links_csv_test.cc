// tests/statistical/links_csv_test.cc — links.csv against the link models' nominal values, for
// every link kind, from whole campaigns at fixed seeds.
//
// Bounds (99.9 %, two-sided): a count k of n packets lies within n p +- 3.29 sqrt(n s2), with
// s2 = p (1 - p) for independent packets and, for Markov links, the asymptotic variance of the
// event indicator, s2 = p (1 - p) + 2 sum_{k>=1} Cov(g(S_0), g(S_k)) with g(s) = P(event | s)
// (runs start from the stationary law; the finite-run variance is below this bound for the
// positively correlated chains used here). Delay laws of independent packets pass a chi-square
// test at the 0.999 quantile of chi^2(bins - 1), bins pooled to expected counts >= 5. Mean loss-run
// lengths of independent packets (and of Gilbert's chain, loss 0 / 1) are geometric: the mean of
// c runs lies within 3.29 sd / sqrt(c) of the nominal mean.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <boost/math/distributions/chi_squared.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "models/plant.h"
#include "sim/run/campaign.h"
#include "sim/run/link_report.h"
#include "sim/scenario/scenario.h"
#include "test_util.h"

namespace ncosim::sim {
namespace {

constexpr double kZ = 3.29;

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string cur;
  std::stringstream ss(s);
  while (std::getline(ss, cur, sep)) out.push_back(cur);
  if (!s.empty() && s.back() == sep) out.emplace_back();
  return out;
}

std::vector<double> numbers(const std::string& s) {
  std::vector<double> v;
  if (s.empty()) return v;
  for (const auto& f : split(s, ';')) v.push_back(std::stod(f));
  return v;
}

using Row = std::map<std::string, std::string>;

std::vector<Row> parse(const std::string& csv) {
  std::stringstream ss(csv);
  std::string line;
  std::getline(ss, line);
  const auto header = split(line, ',');
  std::vector<Row> rows;
  while (std::getline(ss, line)) {
    const auto f = split(line, ',');
    Row r;
    for (std::size_t i = 0; i < header.size() && i < f.size(); ++i) r[header[i]] = f[i];
    rows.push_back(r);
  }
  return rows;
}

std::string scenario(const std::string& link, int periods, int runs,
                     const std::string& extra = "") {
  return fmt::format(R"(title = "links"
[run]
periods = {}
warmup = 0
runs = {}
seed = 17
[plant]
kind = "lti"
A = [[0.5]]
Bw = [[1.0]]
W = [[1.0]]
[[sensor]]
name = "s1"
C = [[1.0]]
R = [[1.0]]
link = "net"
{}
[[link]]
name = "net"
{}
[[estimator]]
name = "ol"
kind = "open_loop"
)",
                     periods, runs, extra, link);
}

struct Outcome {
  std::unique_ptr<LoadedScenario> loaded;
  std::vector<Row> rows;
};

Outcome run(const std::string& text) {
  const auto dir =
      std::filesystem::temp_directory_path() / fmt::format("ncosim_links_{}", ::getpid());
  std::filesystem::create_directories(dir);
  const auto file = dir / "s.toml";
  std::ofstream(file) << text;
  Outcome r;
  r.loaded = std::make_unique<LoadedScenario>(load_cases(file.string(), {}));
  std::vector<CampaignResult> results;
  std::vector<const Scenario*> scs;
  std::vector<const CampaignResult*> res;
  std::vector<std::vector<std::string>> labels;
  for (const auto& c : r.loaded->cases) {
    CampaignOptions o;
    o.time_estimators = false;
    o.threads = 2;
    results.push_back(run_campaign(*c.scenario, o));
  }
  for (std::size_t c = 0; c < results.size(); ++c) {
    scs.push_back(r.loaded->cases[c].scenario.get());
    res.push_back(&results[c]);
    labels.push_back(r.loaded->cases[c].labels);
  }
  r.rows = parse(links_csv(r.loaded->sweeps, labels, scs, res));
  std::filesystem::remove_all(dir);
  return r;
}

::testing::AssertionResult CountWithin(const std::string& what, double k, double n, double p,
                                       double s2) {
  const double half = kZ * std::sqrt(n * s2);
  const double dev = std::abs(k - n * p);
  const std::string msg =
      fmt::format("{}: {} of {} = {:.6g}, nominal {:.6g}, |k - np| = {:.4g} vs 99.9% bound {:.4g}",
                  what, k, n, k / n, p, dev, half);
  ::testing::Test::RecordProperty(what, msg);
  if (dev <= half + 1e-9) return ::testing::AssertionSuccess() << msg;
  return ::testing::AssertionFailure() << msg;
}

// Chi-square of the outcomes {lost, delay 0..D, delay > D} of `n` independent packets.
::testing::AssertionResult DelayLawFits(const Row& r) {
  const double n = std::stod(r.at("packets_sent"));
  const double delivered = std::stod(r.at("packets_delivered"));
  const auto obs = numbers(r.at("delay_pmf"));
  const auto nom = numbers(r.at("nominal_delay_pmf"));
  const double loss = 1.0 - std::stod(r.at("nominal_delivered_ratio"));
  std::vector<double> o{n - delivered}, e{n * loss};
  double rest = 1.0 - loss;
  for (std::size_t d = 0; d < nom.size(); ++d) {
    o.push_back(d < obs.size() ? obs[d] * n : 0.0);
    e.push_back(nom[d] * n);
    rest -= nom[d];
  }
  o.push_back(0.0);
  e.push_back(std::max(0.0, rest) * n);
  // Pool adjacent bins until each expects >= 5.
  std::vector<double> po, pe;
  double ao = 0.0, ae = 0.0;
  for (std::size_t i = 0; i < o.size(); ++i) {
    ao += o[i];
    ae += e[i];
    if (ae >= 5.0) {
      po.push_back(ao);
      pe.push_back(ae);
      ao = ae = 0.0;
    }
  }
  if (!pe.empty()) {
    po.back() += ao;
    pe.back() += ae;
  }
  double chi2 = 0.0;
  for (std::size_t i = 0; i < po.size(); ++i) chi2 += (po[i] - pe[i]) * (po[i] - pe[i]) / pe[i];
  if (po.size() < 2) return ::testing::AssertionSuccess() << "one bin";
  const double crit =
      boost::math::quantile(boost::math::chi_squared(static_cast<double>(po.size() - 1)), 0.999);
  const std::string msg = fmt::format("delay law {}: chi2 = {:.4g} on {} bins, critical {:.4g}",
                                      r.at("kind"), chi2, po.size(), crit);
  ::testing::Test::RecordProperty("delay_law_" + r.at("kind"), msg);
  if (chi2 <= crit) return ::testing::AssertionSuccess() << msg;
  return ::testing::AssertionFailure() << msg;
}

// Mean of geometric run lengths with continuation probability q: mean 1 / (1 - q), variance
// q / (1 - q)^2.
::testing::AssertionResult GeometricBurstMean(const Row& r, double q) {
  const double c = std::stod(r.at("bursts"));
  const double mean = std::stod(r.at("burst_mean"));
  const double nominal = std::stod(r.at("nominal_burst_mean"));
  const double half = kZ * std::sqrt(q) / (1.0 - q) / std::sqrt(c);
  const std::string msg =
      fmt::format("burst mean {}: {:.5g} over {} runs, nominal {:.5g}, 99.9% bound {:.4g}",
                  r.at("kind"), mean, c, nominal, half);
  // links.csv prints 6 significant digits.
  if (std::abs(nominal - 1.0 / (1.0 - q)) > 5e-6 * nominal)
    return ::testing::AssertionFailure() << "nominal " << msg;
  if (std::abs(mean - nominal) <= half) return ::testing::AssertionSuccess() << msg;
  return ::testing::AssertionFailure() << msg;
}

// Asymptotic variance per packet of the indicator of an event with P(event | state s) = g(s).
double markov_s2(const Eigen::MatrixXd& T, const Eigen::VectorXd& g) {
  const Eigen::VectorXd pi = models::stationary_law(T);
  const double p = pi.dot(g);
  double s2 = p * (1.0 - p);
  Eigen::VectorXd tk = g;
  for (int k = 1; k < 100000; ++k) {
    tk = T * tk;
    const double cov = pi.cwiseProduct(g - Eigen::VectorXd::Constant(g.size(), p)).dot(tk);
    s2 += 2.0 * cov;
    if (std::abs(cov) < 1e-14) break;
  }
  return s2;
}

TEST(LinksCsv, IndependentKindsMatchTheirNominalLossDelayLawAndBurstLength) {
  const std::vector<std::string> links{
      "kind = \"bernoulli\"\nloss = 0.3\ndelay = 2",
      "kind = \"delay\"\npmf = [0.5, 0.2, 0.1]",
      "kind = \"negative_binomial\"\nsuccesses = 3\np = 0.5\nloss = 0.2",
      "kind = \"arrival_cdf\"\ncdf = [0.4, 0.7]\ntail = 0.85",
  };
  for (const auto& l : links) {
    const Outcome r = run(scenario(l, 20000, 4));
    ASSERT_EQ(r.rows.size(), 1u) << l;
    const Row& row = r.rows[0];
    EXPECT_EQ(row.at("sender"), "s1");
    EXPECT_EQ(row.at("runs"), "4");
    EXPECT_EQ(row.at("packets_sent"), "80000");
    const double n = std::stod(row.at("packets_sent"));
    const double p = std::stod(row.at("nominal_delivered_ratio"));
    EXPECT_TRUE(CountWithin(row.at("kind") + " delivered", std::stod(row.at("packets_delivered")),
                            n, p, p * (1 - p)));
    EXPECT_TRUE(DelayLawFits(row));
    EXPECT_TRUE(GeometricBurstMean(row, 1.0 - p));
    EXPECT_LE(std::stoi(row.at("burst_p95")), std::stoi(row.at("burst_max")));
    EXPECT_EQ(row.at("state_occupancy"), "");
  }
}

TEST(LinksCsv, IndependentCopiesCountEveryCopyAtItsDelay) {
  const Outcome r =
      run(scenario("kind = \"delay\"\npmf = [0.6, 0.5, 0.3]\nindependent = true", 20000, 3));
  ASSERT_EQ(r.rows.size(), 1u);
  const Row& row = r.rows[0];
  const double n = std::stod(row.at("packets_sent"));
  const auto obs = numbers(row.at("delay_pmf"));
  const auto nom = numbers(row.at("nominal_delay_pmf"));
  ASSERT_EQ(obs.size(), 3u);
  ASSERT_EQ(nom.size(), 3u);
  for (std::size_t d = 0; d < 3; ++d) {
    const std::vector<double> pmf{0.6, 0.5, 0.3};
    EXPECT_NEAR(nom[d], pmf[d], 1e-12);
    EXPECT_TRUE(
        CountWithin(fmt::format("copy {}", d), obs[d] * n, n, nom[d], nom[d] * (1 - nom[d])));
  }
  const double lost = 0.4 * 0.5 * 0.7;
  EXPECT_NEAR(std::stod(row.at("nominal_delivered_ratio")), 1.0 - lost, 1e-9);
  EXPECT_TRUE(CountWithin("delivered", std::stod(row.at("packets_delivered")), n, 1 - lost,
                          lost * (1 - lost)));
}

TEST(LinksCsv, GilbertBurstsAreGeometricAndGilbertElliottLossAndOccupancyFollowTheChain) {
  {  // Gilbert (loss 0 / 1): runs of losses are the bad state's sojourns, geometric with 1 - p_bg.
    const Outcome r = run(scenario(
        "kind = \"gilbert_elliott\"\np_good_to_bad = 0.05\np_bad_to_good = 0.25", 50000, 4));
    const Row& row = r.rows.at(0);
    EXPECT_NEAR(std::stod(row.at("nominal_burst_mean")), 4.0, 1e-9);
    EXPECT_TRUE(GeometricBurstMean(row, 0.75));
  }
  // General Gilbert–Elliott: loss in both states.
  Eigen::MatrixXd T(2, 2);
  T << 0.97, 0.03, 0.1, 0.9;
  const Outcome r =
      run(scenario("kind = \"gilbert_elliott\"\np_good_to_bad = 0.03\np_bad_to_good = "
                   "0.1\nloss_good = 0.05\nloss_bad = 0.7",
                   50000, 4));
  const Row& row = r.rows.at(0);
  const double n = std::stod(row.at("packets_sent"));
  const Eigen::Vector2d loss(0.05, 0.7);
  const Eigen::Vector2d delivered = Eigen::Vector2d::Ones() - loss;
  const double p = std::stod(row.at("nominal_delivered_ratio"));
  const Eigen::VectorXd pi = models::stationary_law(T);
  EXPECT_NEAR(p, pi.dot(delivered), 1e-12);
  EXPECT_TRUE(CountWithin("GE delivered", std::stod(row.at("packets_delivered")), n, p,
                          markov_s2(T, delivered)));
  const auto occ = numbers(row.at("state_occupancy"));
  const auto nom = numbers(row.at("nominal_state_occupancy"));
  ASSERT_EQ(occ.size(), 2u);
  ASSERT_EQ(nom.size(), 2u);
  for (int s = 0; s < 2; ++s) {
    Eigen::VectorXd g = Eigen::VectorXd::Zero(2);
    g(s) = 1.0;
    EXPECT_NEAR(nom[static_cast<std::size_t>(s)], pi(s), 1e-6);
    EXPECT_TRUE(CountWithin(fmt::format("GE state {}", s), occ[static_cast<std::size_t>(s)] * n, n,
                            pi(s), markov_s2(T, g)));
  }
  // The nominal mean burst: P(L) / (P(L) - P(L, L)).
  const double pl = pi.dot(loss), pll = pi.cwiseProduct(loss).dot(T * loss);
  EXPECT_NEAR(std::stod(row.at("nominal_burst_mean")), pl / (pl - pll), 1e-5);
}

TEST(LinksCsv, MarkovWithPerStateDelaysMatchesLossDelayRatesAndOccupancy) {
  Eigen::MatrixXd T(3, 3);
  T << 0.9, 0.08, 0.02, 0.1, 0.8, 0.1, 0.05, 0.15, 0.8;
  const Eigen::Vector3d loss(0.02, 0.3, 0.9);
  const std::vector<std::vector<double>> pmf{{1.0}, {0.5, 0.5}, {0.2, 0.3, 0.5}};
  const Outcome r = run(scenario(
      "kind = \"markov\"\ntransition = [[0.9, 0.08, 0.02], [0.1, 0.8, 0.1], [0.05, 0.15, 0.8]]\n"
      "loss = [0.02, 0.3, 0.9]\ndelay_pmf = [[1.0], [0.5, 0.5], [0.2, 0.3, 0.5]]",
      50000, 4));
  const Row& row = r.rows.at(0);
  const double n = std::stod(row.at("packets_sent"));
  const auto obs = numbers(row.at("delay_pmf"));
  const auto nom = numbers(row.at("nominal_delay_pmf"));
  ASSERT_EQ(obs.size(), 3u);
  for (std::size_t d = 0; d < 3; ++d) {
    Eigen::Vector3d g;
    for (int s = 0; s < 3; ++s) {
      const auto& p = pmf[static_cast<std::size_t>(s)];
      g(s) = (1.0 - loss(s)) * (d < p.size() ? p[d] : 0.0);
    }
    EXPECT_TRUE(
        CountWithin(fmt::format("markov delay {}", d), obs[d] * n, n, nom[d], markov_s2(T, g)));
  }
  const auto occ = numbers(row.at("state_occupancy"));
  const Eigen::VectorXd pi = models::stationary_law(T);
  ASSERT_EQ(occ.size(), 3u);
  for (int s = 0; s < 3; ++s) {
    Eigen::VectorXd g = Eigen::VectorXd::Zero(3);
    g(s) = 1.0;
    EXPECT_TRUE(CountWithin(fmt::format("markov state {}", s), occ[static_cast<std::size_t>(s)] * n,
                            n, pi(s), markov_s2(T, g)));
  }
}

TEST(LinksCsv, TraceRowsCountTheReplayExactly) {
  const auto dir =
      std::filesystem::temp_directory_path() / fmt::format("ncosim_links_trace_{}", ::getpid());
  std::filesystem::create_directories(dir);
  // 0, lost, 1, lost, lost, 0, ... (period 6): per 6 packets 3 delivered, runs of 1 and 2.
  std::ofstream out(dir / "t.csv");
  const char* pattern[] = {"0", "", "1", "", "", "0"};
  for (int i = 0; i < 600; ++i) out << i << "," << pattern[i % 6] << "\n";
  out.close();
  const Outcome r = run(
      scenario(fmt::format("kind = \"trace\"\nfile = \"{}\"", (dir / "t.csv").string()), 600, 3));
  std::filesystem::remove_all(dir);
  const Row& row = r.rows.at(0);
  EXPECT_EQ(row.at("packets_sent"), "1800");
  EXPECT_EQ(row.at("packets_delivered"), "900");
  EXPECT_EQ(row.at("delay_pmf"), "0.333333;0.166667");
  EXPECT_EQ(row.at("nominal_delay_pmf"), "0.333333;0.166667");
  EXPECT_EQ(row.at("burst_mean"), "1.5");
  EXPECT_EQ(row.at("nominal_burst_mean"), "1.5");
  EXPECT_EQ(row.at("burst_p95"), "2");
  EXPECT_EQ(row.at("burst_max"), "2");
}

TEST(LinksCsv, SharedLinkGivesARowPerSenderAndAMarkovBurstNominalOnlyWhenStepsAreRegular) {
  const std::string s2 = "[[sensor]]\nname = \"s2\"\nC = [[1.0]]\nR = [[1.0]]\nlink = \"net\"\n";
  {  // Per packet, the two senders interleave on one chain: no nominal run length.
    const Outcome r = run(scenario(
        "kind = \"gilbert_elliott\"\np_good_to_bad = 0.1\np_bad_to_good = 0.3\nstep = \"packet\"",
        2000, 2, s2));
    ASSERT_EQ(r.rows.size(), 2u);
    EXPECT_EQ(r.rows[0].at("sender"), "s1");
    EXPECT_EQ(r.rows[1].at("sender"), "s2");
    for (const auto& row : r.rows) {
      EXPECT_EQ(row.at("packets_sent"), "4000");
      EXPECT_EQ(row.at("step"), "packet");
      EXPECT_EQ(row.at("nominal_burst_mean"), "");
      EXPECT_NE(row.at("burst_mean"), "");
    }
  }
  // Per period (the default), each sender meets the chain once per period: runs of the bad state.
  const Outcome r = run(scenario(
      "kind = \"gilbert_elliott\"\np_good_to_bad = 0.1\np_bad_to_good = 0.3", 20000, 4, s2));
  ASSERT_EQ(r.rows.size(), 2u);
  for (const auto& row : r.rows) {
    EXPECT_EQ(row.at("step"), "period");
    EXPECT_TRUE(GeometricBurstMean(row, 0.7));
  }
}

TEST(LinksCsv, PerPeriodChainSeenEveryThirdPeriodHasTheRunsOfTheCubedChain) {
  std::string text =
      scenario("kind = \"gilbert_elliott\"\np_good_to_bad = 0.1\np_bad_to_good = 0.3", 60000, 4);
  const std::string from = "link = \"net\"\n";
  text.replace(text.find(from), from.size(), from + "every = 3\n");
  const Outcome r = run(text);
  const Row& row = r.rows.at(0);
  Eigen::Matrix2d T;
  T << 0.9, 0.1, 0.3, 0.7;
  const Eigen::Matrix2d T3 = T * T * T;
  EXPECT_EQ(row.at("packets_sent"), "80000");
  EXPECT_TRUE(GeometricBurstMean(row, T3(1, 1)));
}

TEST(LinksCsv, ActuatorChannelsGetTheirOwnRows) {
  auto loaded = load_cases(testing::source_path("scenarios/cstr_mode_estimation.toml"),
                           {"run.runs=20", "run.periods=2001"});
  const Scenario& sc = *loaded.cases[0].scenario;
  CampaignOptions o;
  o.time_estimators = false;
  const CampaignResult res = run_campaign(sc, o);
  const auto rows = parse(links_csv({}, {{}}, {&sc}, {&res}));
  ASSERT_EQ(rows.size(), 2u);
  Eigen::MatrixXd T(2, 2);
  T << 0.8, 0.2, 0.4, 0.6;
  for (const auto& row : rows) {
    EXPECT_EQ(row.at("packets_sent"), "40020");
    const double n = 40020;
    EXPECT_TRUE(CountWithin(row.at("sender") + " delivered", std::stod(row.at("packets_delivered")),
                            n, 2.0 / 3.0, markov_s2(T, Eigen::Vector2d(1.0, 0.0))));
    EXPECT_NEAR(std::stod(row.at("nominal_burst_mean")), 2.5, 1e-9);  // 1 / p_bad_to_good
  }
  EXPECT_EQ(rows[0].at("sender"), "u1");
  EXPECT_EQ(rows[1].at("sender"), "u2");
}

}  // namespace
}  // namespace ncosim::sim

namespace ncosim::sim {
namespace {

// Sensors on one link that sample at the same period send in the order their samples were
// scheduled (scenarios/README.md, "Event order within one period"): s2 (every = 2, sampled at
// k - 2) before s1 (every = 1, sampled at k - 1) at k = 2 and 4. A trace link hands its rows
// out in sending order: s1 gets rows 0, 2, 4, 5, 7, 8 and s2 rows 1, 3, 6, the only delivered
// ones. In the sensors' index order s2 would get rows 1, 4, 7 instead.
TEST(LinksCsv, SensorsDueTogetherSendInTheOrderTheirSamplesWereScheduled) {
  const auto dir =
      std::filesystem::temp_directory_path() / fmt::format("ncosim_links_{}", ::getpid());
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "order.csv") << "seq,delay\n0,\n1,0\n2,\n3,0\n4,\n5,\n6,0\n7,\n8,\n";
  const std::string s2 =
      "[[sensor]]\nname = \"s2\"\nC = [[1.0]]\nR = [[1.0]]\nlink = \"net\"\nevery = 2\n";
  const Outcome r = run(scenario("kind = \"trace\"\nfile = \"order.csv\"", 6, 1, s2));
  ASSERT_EQ(r.rows.size(), 2u);
  EXPECT_EQ(r.rows[0].at("sender"), "s1");
  EXPECT_EQ(r.rows[0].at("packets_sent"), "6");
  EXPECT_EQ(r.rows[0].at("packets_delivered"), "0");
  EXPECT_EQ(r.rows[1].at("sender"), "s2");
  EXPECT_EQ(r.rows[1].at("packets_sent"), "3");
  EXPECT_EQ(r.rows[1].at("packets_delivered"), "3");
}

}  // namespace
}  // namespace ncosim::sim
