// tests/models/channel_test.cc — the fitting machinery on small inputs: the forward recursion
// against brute-force enumeration, closed forms, the Gilbert–Elliott conversion by mean loss and
// mean burst, the per-flow link counters, per-period stepping of Markov links, bad input.
#include <gtest/gtest.h>

#include <cmath>

#include "kernel/rng.h"
#include "models/fit.h"
#include "models/link.h"
#include "models/link_stats.h"

namespace ncosim::models {
namespace {

TEST(Fit, ForwardLogLikelihoodEqualsTheSumOverEveryStatePath) {
  FateHmm h;
  h.transition.resize(2, 2);
  h.transition << 0.9, 0.1, 0.3, 0.7;
  h.emission.resize(2, 3);
  h.emission << 0.1, 0.6, 0.3, 0.7, 0.1, 0.2;
  const std::vector<int> sym{1, 0, 0, 2, 1, 0};
  const Eigen::VectorXd pi = h.stationary();
  double total = 0.0;
  for (int path = 0; path < 64; ++path) {
    double p = 1.0;
    int prev = -1;
    for (int t = 0; t < 6; ++t) {
      const int s = (path >> t) & 1;
      p *= (t == 0 ? pi(s) : h.transition(prev, s)) *
           h.emission(s, sym[static_cast<std::size_t>(t)]);
      prev = s;
    }
    total += p;
  }
  EXPECT_NEAR(hmm_loglik(h, sym), std::log(total), 1e-12);
}

TEST(Fit, IidFamiliesAreTheirClosedForms) {
  // 6 lost, 10 at delay 0, 4 at delay 1.
  std::vector<int> sym;
  for (int i = 0; i < 6; ++i) sym.push_back(0);
  for (int i = 0; i < 10; ++i) sym.push_back(1);
  for (int i = 0; i < 4; ++i) sym.push_back(2);
  const FitResult d = fit_family("delay", sym, FitOptions{});
  EXPECT_EQ(d.parameters, 2);
  EXPECT_NEAR(d.loglik, 6 * std::log(0.3) + 10 * std::log(0.5) + 4 * std::log(0.2), 1e-9);
  EXPECT_NEAR(d.aic, 4 - 2 * d.loglik, 1e-9);
  EXPECT_NEAR(d.bic, 2 * std::log(20.0) - 2 * d.loglik, 1e-9);
  EXPECT_NE(d.link_toml.find("pmf = [0.5, 0.2]"), std::string::npos) << d.link_toml;
  EXPECT_THROW(fit_family("bernoulli", sym, FitOptions{}), std::domain_error);  // two delays
  std::vector<int> one(sym.begin(), sym.begin() + 16);
  const FitResult b = fit_family("bernoulli", one, FitOptions{});
  EXPECT_NE(b.link_toml.find("loss = 0.375\ndelay = 0"), std::string::npos) << b.link_toml;
}

TEST(Fit, UnknownFamiliesAndTooFewPacketsAreRejected) {
  const std::vector<int> sym{0, 1, 1, 0, 1};
  EXPECT_EQ(family_states("markov1"), 0);
  EXPECT_EQ(family_states("markov03"), 0);
  EXPECT_EQ(family_states("markov3"), 3);
  EXPECT_THROW(fit_family("hmm", sym, FitOptions{}), std::invalid_argument);
  EXPECT_THROW(fit_family("markov3", sym, FitOptions{}), std::invalid_argument);  // 6 + 3 > 5
  EXPECT_NO_THROW(fit_family("gilbert_elliott", sym, FitOptions{}));              // 4 <= 5
}

// The mean loss and mean burst of a Gilbert–Elliott fit (issue 28): the values a gilbert_elliott
// [[link]] written with mean_loss and mean_burst would have, i.e. the fitted chain's stationary
// loss and mean loss-run length (link.cc), with delta-method 95 % intervals that hold the truth
// (P = 0.02 / 0.27 = 0.074, burst 1 / 0.25 = 4 for a classic Gilbert chain; 20000 packets).
TEST(Fit, GilbertElliottReportsMeanLossAndMeanBurstWithIntervals) {
  kernel::Rng rng = kernel::make_stream(5, 0, 0);
  auto truth = make_gilbert_elliott(0.02, 0.25, 0.0, 1.0);
  truth->reset(rng);
  std::vector<int> sym;
  for (int i = 0; i < 20000; ++i) sym.push_back(truth->transmit(rng) == kLost ? 0 : 1);
  const FitResult r = fit_family("gilbert_elliott", sym, FitOptions{});
  ASSERT_EQ(r.derived.size(), 2u);
  const FitParameter& loss = r.derived[0];
  const FitParameter& burst = r.derived[1];
  EXPECT_EQ(loss.name, "mean_loss");
  EXPECT_EQ(burst.name, "mean_burst");
  const auto fitted = make_gilbert_elliott(r.model.transition(0, 1), r.model.transition(1, 0),
                                           r.model.emission(0, 0), r.model.emission(1, 0));
  EXPECT_NEAR(loss.estimate, fitted->loss_probability(), 1e-9);
  EXPECT_NEAR(burst.estimate, fitted->mean_loss_burst(1).value(), 1e-6);
  EXPECT_LT(loss.ci_low, loss.estimate);
  EXPECT_GT(loss.ci_high, loss.estimate);
  EXPECT_LE(loss.ci_low, 0.02 / 0.27);
  EXPECT_GE(loss.ci_high, 0.02 / 0.27);
  EXPECT_LT(burst.ci_low, burst.estimate);
  EXPECT_GE(burst.ci_low, 1.0);
  EXPECT_LE(burst.ci_low, 4.0);
  EXPECT_GE(burst.ci_high, 4.0);
}

TEST(Fit, FateSymbolsRefuseADelayBeyondWhatTheFamiliesHold) {
  // Issue 29: a delay cast to int overflowed (a wrong symbol, or an out-of-bounds write later).
  EXPECT_EQ(fate_symbols({kMaxFitDelay, std::nullopt, 0}),
            (std::vector<int>{static_cast<int>(kMaxFitDelay) + 1, 0, 1}));
  for (const std::int64_t d :
       {kMaxFitDelay + 1, std::int64_t{4611686018427387903}, std::int64_t{9223372036854775806}}) {
    EXPECT_THROW(fate_symbols({0, d}), std::out_of_range) << d;
  }
}

TEST(Fit, GilbertElliottFitsAShortBurstyTraceAndPrintsAReadableTable) {
  kernel::Rng rng = kernel::make_stream(5, 0, 0);
  auto link = make_gilbert_elliott(0.02, 0.25, 0.0, 1.0);
  link->reset(rng);
  std::vector<int> sym;
  for (int i = 0; i < 20000; ++i) sym.push_back(link->transmit(rng) == kLost ? 0 : 1);
  FitOptions o;
  o.intervals = false;
  const FitResult r = fit_family("gilbert_elliott", sym, o);
  EXPECT_TRUE(r.converged);
  EXPECT_NEAR(r.model.transition(1, 0), 0.25, 0.05);
  EXPECT_NEAR(r.model.emission(1, 0), 1.0, 0.05);
  EXPECT_NE(r.link_toml.find("kind = \"gilbert_elliott\""), std::string::npos);
  // Goodness of fit: the model's run-length law has (nearly) all its mass within the longest
  // run seen and the trace's mean; the lag-1 autocorrelations agree. About 370 runs: the mean's
  // standard error is ~4.5 %, the lag-1 autocorrelation's ~0.02.
  double mass = 0.0, mean_model = 0.0, mean_obs = 0.0;
  for (std::size_t L = 0; L < r.burst_model.size(); ++L) {
    mass += r.burst_model[L];
    mean_model += static_cast<double>(L + 1) * r.burst_model[L];
    mean_obs += static_cast<double>(L + 1) * r.burst_observed[L];
  }
  EXPECT_GT(mass, 0.99);
  EXPECT_LE(mass, 1.0 + 1e-12);
  EXPECT_NEAR(mean_model / mass, mean_obs, 0.15 * mean_obs);
  ASSERT_FALSE(r.acf_model.empty());
  EXPECT_NEAR(r.acf_model[0], r.acf_observed[0], 0.08);
  EXPECT_GE(r.burst_tv, 0.0);
  EXPECT_LE(r.burst_tv, 1.0);
}

TEST(GilbertElliottByMean, ConvertsExactlyAndRejectsWhatNoChainReaches) {
  for (const auto& [P, b, lg, lb] :
       std::vector<std::tuple<double, double, double, double>>{{0.1, 4.0, 0.0, 1.0},
                                                               {0.2, 2.5, 0.05, 0.8},
                                                               {0.3, 1.3, 0.1, 0.9},
                                                               {0.05, 1.5, 0.01, 0.5}}) {
    const GilbertElliottByMean g = gilbert_elliott_by_mean(P, b, lg, lb);
    ASSERT_TRUE(g.error.empty()) << g.error;
    const auto link = make_gilbert_elliott(g.p_good_to_bad, g.p_bad_to_good, lg, lb);
    EXPECT_NEAR(link->loss_probability(), P, 1e-12);
    EXPECT_NEAR(link->mean_loss_burst(1).value(), b, 1e-9);
  }
  // Classic Gilbert: p_bg = 1 / b, p_gb = P / (b (1 - P)).
  const GilbertElliottByMean g = gilbert_elliott_by_mean(0.1, 4.0, 0.0, 1.0);
  EXPECT_NEAR(g.p_bad_to_good, 0.25, 1e-12);
  EXPECT_NEAR(g.p_good_to_bad, 0.1 * 0.25 / 0.9, 1e-12);
  EXPECT_EQ(gilbert_elliott_by_mean(0.5, 4.0, 0.0, 0.4).error_key, "mean_loss");
  EXPECT_EQ(gilbert_elliott_by_mean(0.1, 0.5, 0.0, 1.0).error_key, "mean_burst");
  EXPECT_NE(gilbert_elliott_by_mean(0.1, 0.5, 0.0, 1.0).error.find("got 0.5"), std::string::npos);
  // lg = 0.05, lb = 0.2, P = 0.1: the loss indicator's runs cannot be long.
  const auto longest = gilbert_elliott_by_mean(0.1, 50.0, 0.05, 0.2);
  EXPECT_EQ(longest.error_key, "mean_burst");
  EXPECT_NE(longest.error.find("expected mean_burst <"), std::string::npos) << longest.error;
}

TEST(LinkCounters, CountRunsDelaysStatesAndCloseAnOpenRun) {
  LinkCounters c;
  const std::vector<std::int64_t> lost, d0{0}, d2{2}, both{0, 1};
  c.record(lost, 0);
  c.record(lost, 1);
  c.record(d0, 1);
  c.record(both, 0);
  c.record(lost, 0);
  c.record(d2, 0);
  c.record(kLost, 1);
  c.record(kLost, 1);
  c.record(kLost, 1);
  c.close();
  EXPECT_EQ(c.sent, 9);
  EXPECT_EQ(c.delivered, 3);
  EXPECT_EQ(c.copies, (std::vector<std::int64_t>{2, 1, 1}));
  EXPECT_EQ(c.bursts, (std::vector<std::int64_t>{1, 1, 1}));
  EXPECT_EQ(c.states, (std::vector<std::int64_t>{4, 5}));
  const BurstSummary b = summarise_bursts(c.bursts);
  EXPECT_EQ(b.count, 3);
  EXPECT_DOUBLE_EQ(*b.mean, 2.0);
  EXPECT_EQ(*b.p95, 3);
  EXPECT_EQ(*b.max, 3);
  LinkCounters sum;
  sum.add(c);
  sum.add(c);
  EXPECT_EQ(sum.bursts, (std::vector<std::int64_t>{2, 2, 2}));
  EXPECT_FALSE(summarise_bursts({}).mean);
}

TEST(MarkovLinkStep, PerPeriodEqualsPerPacketForOneSenderEveryPeriod) {
  Eigen::MatrixXd T(3, 3);
  T << 0.8, 0.15, 0.05, 0.2, 0.7, 0.1, 0.1, 0.3, 0.6;
  const MarkovLink packet(T, {0.05, 0.4, 0.9}, {{1.0}, {0.5, 0.5}, {0.2, 0.8}}, {},
                          MarkovLink::Step::kPacket);
  const MarkovLink period(T, {0.05, 0.4, 0.9}, {{1.0}, {0.5, 0.5}, {0.2, 0.8}}, {},
                          MarkovLink::Step::kPeriod);
  auto a = packet.clone();
  auto b = period.clone();
  kernel::Rng ra = kernel::make_stream(9, 1, 2), rb = kernel::make_stream(9, 1, 2);
  a->reset(ra);
  b->reset(rb);
  for (std::int64_t k = 0; k < 5000; ++k) {
    a->advance(k, ra);
    b->advance(k, rb);
    ASSERT_EQ(state_of(*a), state_of(*b)) << k;
    ASSERT_EQ(a->transmit(ra), b->transmit(rb)) << k;
  }
}

TEST(MarkovLinkStep, PerPeriodChainMovesWhileTheSenderIsSilent) {
  // Gilbert's chain that always leaves its state: per period it alternates, so a sender every
  // second period always meets the state it started in; per packet it alternates per packet.
  const auto per_period = make_gilbert_elliott(1.0, 1.0, 0.0, 1.0, MarkovLink::Step::kPeriod);
  const auto per_packet = make_gilbert_elliott(1.0, 1.0, 0.0, 1.0, MarkovLink::Step::kPacket);
  kernel::Rng r1 = kernel::make_stream(1, 0, 0), r2 = kernel::make_stream(1, 0, 0);
  per_period->reset(r1);
  per_packet->reset(r2);
  const int s0 = per_period->state(), t0 = per_packet->state();
  for (std::int64_t k = 0; k < 40; k += 2) {
    per_period->advance(k, r1);
    per_packet->advance(k, r2);
    EXPECT_EQ(per_period->state(), s0);
    EXPECT_EQ(per_packet->state(), (t0 + k / 2) % 2);
    (void)per_period->transmit(r1);
    (void)per_packet->transmit(r2);
  }
  // Nominal loss runs of a sender every 3 periods: the chain T^3.
  const auto ge = make_gilbert_elliott(0.1, 0.3, 0.0, 1.0, MarkovLink::Step::kPeriod);
  Eigen::Matrix2d T;
  T << 0.9, 0.1, 0.3, 0.7;
  const Eigen::Matrix2d T3 = T * T * T;
  EXPECT_NEAR(ge->mean_loss_burst(3).value(), 1.0 / T3(1, 0), 1e-12);
  EXPECT_FALSE(ge->mean_loss_burst(std::nullopt));
}

}  // namespace
}  // namespace ncosim::models
