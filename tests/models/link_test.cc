// tests/models/link_test.cc — every link kind: statistics at fixed seeds, delay_pmf by hand,
// trace replay and the trace reader's errors, clone().
//
// Statistical bounds follow from the sample size n: a rate k/n must lie in the two-sided
// 99.9% normal interval n p +- 3.29 sqrt(n p (1 - p)) (exact equality when p is 0 or 1);
// a distribution passes a chi-square goodness-of-fit test whose critical value is the
// 0.999 quantile of chi^2(bins - 1), after pooling adjacent bins with expected count < 5.
// Samples of a Markov link are thinned so that consecutive kept packets are practically
// independent (second eigenvalue^gap < 1e-6).
#include "models/link.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <boost/math/distributions/chi_squared.hpp>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "kernel/rng.h"

namespace ncosim::models {
namespace {

using kernel::Rng;

constexpr double kZ999 = 3.29;  // two-sided 99.9% quantile of the standard normal

Rng stream(std::uint64_t seed) {
  return kernel::make_stream(seed, 0, kernel::stream_id(kernel::StreamKind::kLink, 0));
}

// k successes out of n inside the 99.9% interval around n p. The figures go into the
// failure message and into the test's XML properties under `label`.
::testing::AssertionResult RateWithinBound(const std::string& label, std::int64_t k, std::int64_t n,
                                           double p) {
  const double nn = static_cast<double>(n);
  const double half = kZ999 * std::sqrt(nn * p * (1.0 - p));
  const double dev = std::abs(static_cast<double>(k) - nn * p);
  std::ostringstream os;
  os << std::setprecision(6) << label << ": " << k << "/" << n << " = "
     << static_cast<double>(k) / nn << ", expected " << p << ", 99.9% bound |k - np| <= " << half
     << " (got " << dev << ")";
  ::testing::Test::RecordProperty(label, os.str());
  if (dev <= half + 1e-9) return ::testing::AssertionSuccess() << os.str();
  return ::testing::AssertionFailure() << os.str();
}

// Chi-square goodness of fit of counts `observed` (one per outcome) against `probs`
// (same length, summing to 1).
::testing::AssertionResult FitsDistribution(const std::string& label,
                                            const std::vector<std::int64_t>& observed,
                                            const std::vector<double>& probs) {
  if (observed.size() != probs.size()) {
    return ::testing::AssertionFailure() << label << ": size mismatch";
  }
  double total_p = 0.0;
  std::int64_t n = 0;
  for (std::size_t i = 0; i < probs.size(); ++i) {
    total_p += probs[i];
    n += observed[i];
    if (probs[i] == 0.0 && observed[i] > 0) {
      return ::testing::AssertionFailure()
             << label << ": outcome " << i << " has probability 0 but was seen " << observed[i]
             << " times";
    }
  }
  if (std::abs(total_p - 1.0) > 1e-9) {
    return ::testing::AssertionFailure() << label << ": probabilities sum to " << total_p;
  }
  // Pool adjacent outcomes until each pool expects >= 5; a short last pool joins the previous.
  std::vector<double> pool_obs;
  std::vector<double> pool_exp;
  double o = 0.0;
  double e = 0.0;
  for (std::size_t i = 0; i < probs.size(); ++i) {
    o += static_cast<double>(observed[i]);
    e += static_cast<double>(n) * probs[i];
    if (e >= 5.0) {
      pool_obs.push_back(o);
      pool_exp.push_back(e);
      o = e = 0.0;
    }
  }
  if (e > 0.0 || o > 0.0) {
    if (pool_obs.empty()) {
      pool_obs.push_back(o);
      pool_exp.push_back(e);
    } else {
      pool_obs.back() += o;
      pool_exp.back() += e;
    }
  }
  if (pool_obs.size() < 2) {
    return ::testing::AssertionFailure() << label << ": fewer than 2 bins after pooling";
  }
  double chi2 = 0.0;
  for (std::size_t j = 0; j < pool_obs.size(); ++j) {
    chi2 += (pool_obs[j] - pool_exp[j]) * (pool_obs[j] - pool_exp[j]) / pool_exp[j];
  }
  const int df = static_cast<int>(pool_obs.size()) - 1;
  const double critical =
      boost::math::quantile(boost::math::chi_squared_distribution<double>(df), 0.999);
  std::ostringstream os;
  os << std::setprecision(6) << label << ": n = " << n << ", chi2 = " << chi2 << ", df = " << df
     << ", critical(0.999) = " << critical;
  ::testing::Test::RecordProperty(label, os.str());
  if (chi2 <= critical) return ::testing::AssertionSuccess() << os.str();
  os << "; observed/expected per pooled bin:";
  for (std::size_t j = 0; j < pool_obs.size(); ++j) {
    os << " " << pool_obs[j] << "/" << pool_exp[j];
  }
  return ::testing::AssertionFailure() << os.str();
}

// Counts of delays 0..max_delay (a delay beyond max_delay fails the test) and of losses.
struct Tally {
  std::vector<std::int64_t> delays;
  std::int64_t lost = 0;
  std::int64_t delivered() const {
    std::int64_t s = 0;
    for (const auto c : delays) s += c;
    return s;
  }
};

Tally tally(Link& link, Rng& rng, std::int64_t n, std::size_t max_delay) {
  Tally t;
  t.delays.assign(max_delay + 1, 0);
  for (std::int64_t k = 0; k < n; ++k) {
    const std::int64_t d = link.transmit(rng);
    if (d == kLost) {
      ++t.lost;
    } else {
      EXPECT_GE(d, 0);
      EXPECT_LE(d, static_cast<std::int64_t>(max_delay)) << "packet " << k;
      if (d >= 0 && d <= static_cast<std::int64_t>(max_delay))
        ++t.delays[static_cast<std::size_t>(d)];
    }
  }
  return t;
}

// pmf[d] / sum(pmf): the law of the delay of a delivered packet.
std::vector<double> conditional(const std::vector<double>& pmf) {
  double s = 0.0;
  for (const double p : pmf) s += p;
  std::vector<double> out;
  for (const double p : pmf) out.push_back(p / s);
  return out;
}

void ExpectVectorNear(const std::vector<double>& expected, const std::vector<double>& got,
                      double tol) {
  ASSERT_EQ(expected.size(), got.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_NEAR(got[i], expected[i], tol) << "entry " << i;
  }
}

// ---------------------------------------------------------------------------------------
// DelayPmfLink

// Dolz et al. 2014 net1 pmf = [0.3340, 0.3064]: loss = 1 - 0.6404 = 0.3596; a delivered
// packet has delay 0 w.p. 0.3340 / 0.6404 = 0.52155 and 1 w.p. 0.47845. A longer pmf
// [0.45, 0.25, 0.12, 0.05, 0.001] loses 1 - 0.871 = 0.129. n = 200000 packets each.
TEST(DelayPmfLink, LossRateAndDelaysMatchThePmf) {
  const std::vector<std::vector<double>> pmfs = {{0.3340, 0.3064}, {0.45, 0.25, 0.12, 0.05, 0.001}};
  const std::vector<double> losses = {0.3596, 0.129};
  constexpr std::int64_t kN = 200000;
  for (std::size_t c = 0; c < pmfs.size(); ++c) {
    SCOPED_TRACE("pmf case " + std::to_string(c));
    DelayPmfLink link(pmfs[c]);
    EXPECT_NEAR(link.loss_probability(), losses[c], 1e-12);
    Rng rng = stream(2014 + c);
    const Tally t = tally(link, rng, kN, pmfs[c].size() - 1);
    const std::string tag = "delay_pmf_case" + std::to_string(c);
    EXPECT_TRUE(RateWithinBound(tag + "_loss", t.lost, kN, losses[c]));
    EXPECT_TRUE(FitsDistribution(tag + "_delays", t.delays, conditional(pmfs[c])));
  }
}

// delay_pmf(m) is the pmf cut or zero-padded to m + 1 entries, in both modes.
// Exclusive loss = 1 - 0.6404 = 0.3596; independent loss = no copy at all
// = (1 - 0.3340)(1 - 0.3064) = 0.666 * 0.6936 = 0.4619376.
TEST(DelayPmfLink, DelayPmfCutsOrPadsThePmfInBothModes) {
  for (const bool independent : {false, true}) {
    DelayPmfLink link({0.3340, 0.3064}, independent);
    ExpectVectorNear({0.3340}, link.delay_pmf(0), 0.0);
    ExpectVectorNear({0.3340, 0.3064, 0.0, 0.0}, link.delay_pmf(3), 0.0);
    EXPECT_NEAR(link.loss_probability(), independent ? 0.4619376 : 0.3596, 1e-12)
        << "independent = " << independent;
  }
  EXPECT_DOUBLE_EQ(DelayPmfLink({}).loss_probability(), 1.0);
}

// Exclusive mode: transmit_copies is transmit wrapped in at most one copy, draw for draw.
TEST(DelayPmfLink, ExclusiveModeDeliversAtMostTheTransmittedCopy) {
  DelayPmfLink a({0.3340, 0.3064});
  DelayPmfLink b({0.3340, 0.3064});
  Rng ra = stream(1);
  Rng rb = stream(1);
  std::vector<std::int64_t> copies;
  for (int k = 0; k < 1000; ++k) {
    const std::int64_t d = a.transmit(ra);
    b.transmit_copies(rb, copies);
    ASSERT_EQ(copies.size(), d == kLost ? 0u : 1u) << "packet " << k;
    if (d != kLost) {
      EXPECT_EQ(copies[0], d) << "packet " << k;
    }
  }
}

// Independent mode, pmf p = [0.3340, 0.3064, 0.2] (Dolz Remark 2.3): copy d arrives with
// probability p_d independently, so the 8 arrival patterns (c0, c1, c2) have probability
// prod_d (c_d ? p_d : 1 - p_d); e.g. no copy = 0.666 * 0.6936 * 0.8 = 0.36955008.
// n = 200000 packets: each marginal rate within its binomial bound, the 8-cell joint
// table fits the product law (chi-square, df = 7).
TEST(DelayPmfLink, IndependentCopiesArriveIndependently) {
  const std::vector<double> p = {0.3340, 0.3064, 0.2};
  DelayPmfLink link(p, /*independent=*/true);
  constexpr std::int64_t kN = 200000;
  Rng rng = stream(23);
  std::vector<std::int64_t> joint(8, 0);
  std::vector<std::int64_t> marginal(3, 0);
  std::vector<std::int64_t> copies;
  for (std::int64_t k = 0; k < kN; ++k) {
    link.transmit_copies(rng, copies);
    int pattern = 0;
    for (std::size_t i = 0; i < copies.size(); ++i) {
      ASSERT_GE(copies[i], 0);
      ASSERT_LT(copies[i], 3);
      if (i > 0) {
        ASSERT_LT(copies[i - 1], copies[i]) << "copies not distinct and ascending";
      }
      pattern |= 1 << copies[i];
      ++marginal[static_cast<std::size_t>(copies[i])];
    }
    ++joint[static_cast<std::size_t>(pattern)];
  }
  std::vector<double> product(8);
  for (int pattern = 0; pattern < 8; ++pattern) {
    double q = 1.0;
    for (int d = 0; d < 3; ++d) q *= (pattern >> d & 1) ? p[d] : 1.0 - p[d];
    product[static_cast<std::size_t>(pattern)] = q;
  }
  for (std::size_t d = 0; d < 3; ++d) {
    EXPECT_TRUE(RateWithinBound("copy" + std::to_string(d) + "_rate", marginal[d], kN, p[d]));
  }
  EXPECT_TRUE(RateWithinBound("no_copy_rate", joint[0], kN, link.loss_probability()));
  EXPECT_NEAR(link.loss_probability(), 0.36955008, 1e-12);
  EXPECT_TRUE(FitsDistribution("joint_copies", joint, product));
}

// Independent mode, transmit() returns the first delivered copy:
// P[0] = 0.334, P[1] = 0.666 * 0.3064 = 0.2040624, P[2] = 0.666 * 0.6936 * 0.2 = 0.09238752,
// lost = 0.36955008. n = 100000, chi-square over the 4 outcomes (df = 3).
TEST(DelayPmfLink, IndependentTransmitReturnsTheFirstCopy) {
  DelayPmfLink link({0.3340, 0.3064, 0.2}, /*independent=*/true);
  Rng rng = stream(29);
  const Tally t = tally(link, rng, 100000, 2);
  EXPECT_TRUE(FitsDistribution("first_copy", {t.delays[0], t.delays[1], t.delays[2], t.lost},
                               {0.334, 0.2040624, 0.09238752, 0.36955008}));
}

// ---------------------------------------------------------------------------------------
// BernoulliLink

// loss = 0.3, delay = 2: n = 200000, the loss rate within 0.3 +- 3.29 sqrt(0.21 / n)
// = 0.3 +- 0.00337, and every delivered packet has delay exactly 2.
TEST(BernoulliLink, LossRateWithinBinomialBoundAndDelayIsFixed) {
  BernoulliLink link(0.3, 2);
  constexpr std::int64_t kN = 200000;
  Rng rng = stream(31);
  const Tally t = tally(link, rng, kN, 2);
  EXPECT_TRUE(RateWithinBound("bernoulli_loss", t.lost, kN, 0.3));
  EXPECT_EQ(t.delays[0], 0);
  EXPECT_EQ(t.delays[1], 0);
  EXPECT_EQ(t.delays[2], kN - t.lost);
  // The delivered delays' law is the single point 2: exact, nothing to pool.
}

// delay_pmf(m) = (1 - loss) at the delay, 0 elsewhere; nothing when the delay exceeds m.
TEST(BernoulliLink, DelayPmfPutsTheDeliveredMassAtTheDelay) {
  BernoulliLink link(0.3, 2);
  ExpectVectorNear({0.0, 0.0, 0.7, 0.0}, link.delay_pmf(3), 1e-15);
  ExpectVectorNear({0.0, 0.0}, link.delay_pmf(1), 0.0);
  EXPECT_DOUBLE_EQ(link.loss_probability(), 0.3);
  ExpectVectorNear({1.0}, BernoulliLink(0.0, 0).delay_pmf(0), 0.0);
}

// ---------------------------------------------------------------------------------------
// NegativeBinomialLink

// P[d] = C(d + r - 1, d) p^r (1 - p)^d, by the recurrence P[0] = p^r,
// P[d + 1] = P[d] (1 - p) (d + r) / (d + 1) (independent of Boost.Math), up to d = 399
// plus a tail bin.
std::vector<double> nb_law(int r, double p) {
  std::vector<double> law;
  double q = std::pow(p, r);
  double s = 0.0;
  for (int d = 0; d < 400; ++d) {
    law.push_back(q);
    s += q;
    q *= (1.0 - p) * (d + r) / (d + 1.0);
  }
  law.push_back(std::max(0.0, 1.0 - s));
  return law;
}

// Dolz example 2 (r = 3, p = 0.5) with loss 0.2, and r = 2, p = 0.1, loss 0 (mean delay
// r (1 - p) / p = 18: exercises the other branch of Boost's Poisson sampler). n = 100000
// each: loss within the binomial bound (exactly 0 when loss = 0), delivered delays
// chi-square against the closed form.
TEST(NegativeBinomialLink, LossRateAndDelaysMatchTheClosedForm) {
  struct Case {
    int r;
    double p;
    double loss;
  };
  const std::vector<Case> cases = {{3, 0.5, 0.2}, {2, 0.1, 0.0}};
  constexpr std::int64_t kN = 100000;
  for (std::size_t c = 0; c < cases.size(); ++c) {
    SCOPED_TRACE("case " + std::to_string(c));
    NegativeBinomialLink link(cases[c].r, cases[c].p, cases[c].loss);
    Rng rng = stream(37 + c);
    const Tally t = tally(link, rng, kN, 400);
    const std::string tag = "negative_binomial_case" + std::to_string(c);
    EXPECT_TRUE(RateWithinBound(tag + "_loss", t.lost, kN, cases[c].loss));
    EXPECT_TRUE(FitsDistribution(tag + "_delays", t.delays, nb_law(cases[c].r, cases[c].p)));
  }
}

// r = 3, p = 0.5, loss = 0.2: 0.8 * C(d + 2, d) / 8 / 2^d = 0.8 * [1/8, 3/16, 6/32, 10/64]
// = [0.1, 0.15, 0.15, 0.125]. p = 1: every delay is 0, so [1 - loss, 0, 0].
TEST(NegativeBinomialLink, DelayPmfMatchesHandComputation) {
  NegativeBinomialLink link(3, 0.5, 0.2);
  ExpectVectorNear({0.1, 0.15, 0.15, 0.125}, link.delay_pmf(3), 1e-12);
  EXPECT_DOUBLE_EQ(link.loss_probability(), 0.2);
  ExpectVectorNear({0.75, 0.0, 0.0}, NegativeBinomialLink(2, 1.0, 0.25).delay_pmf(2), 0.0);
  NegativeBinomialLink certain(2, 1.0, 0.0);
  Rng rng = stream(41);
  for (int k = 0; k < 100; ++k) EXPECT_EQ(certain.transmit(rng), 0);
}

// ---------------------------------------------------------------------------------------
// ArrivalCdfLink

// cdf = [0, 0.05, 0.4, 0.6], tail = 0.75: P[d] = [0, 0.05, 0.35, 0.2, 0.15] for d = 0..4
// (d = 4 = cdf.size() takes tail - cdf.back()), lost 0.25, never a delay > 4 or 0.
TEST(ArrivalCdfLink, DelayPmfDifferencesTheCdf) {
  ArrivalCdfLink link({0.0, 0.05, 0.4, 0.6}, 0.75);
  ExpectVectorNear({0.0, 0.05, 0.35, 0.2, 0.15, 0.0, 0.0}, link.delay_pmf(6), 1e-15);
  ExpectVectorNear({0.0, 0.05}, link.delay_pmf(1), 1e-15);
  EXPECT_DOUBLE_EQ(link.loss_probability(), 0.25);
  // An empty cdf: lambda_h = tail for every h, so delay 0 w.p. tail.
  ExpectVectorNear({0.9, 0.0, 0.0}, ArrivalCdfLink({}, 0.9).delay_pmf(2), 1e-15);
}

// Same link, n = 200000: loss within 0.25 +- 3.29 sqrt(0.1875 / n) = 0.25 +- 0.0032;
// delivered delays chi-square against [0.05, 0.35, 0.2, 0.15] / 0.75 (delay 0 never seen).
TEST(ArrivalCdfLink, LossRateAndDelaysMatchTheCdf) {
  ArrivalCdfLink link({0.0, 0.05, 0.4, 0.6}, 0.75);
  constexpr std::int64_t kN = 200000;
  Rng rng = stream(43);
  const Tally t = tally(link, rng, kN, 4);
  EXPECT_TRUE(RateWithinBound("arrival_cdf_loss", t.lost, kN, 0.25));
  EXPECT_TRUE(
      FitsDistribution("arrival_cdf_delays", t.delays, conditional({0.0, 0.05, 0.35, 0.2, 0.15})));
}

// ---------------------------------------------------------------------------------------
// MarkovLink and Gilbert–Elliott

// Birth–death chain T = [[0.9, 0.1, 0], [0.2, 0.7, 0.1], [0, 0.4, 0.6]]: detailed balance
// pi0 0.1 = pi1 0.2, pi1 0.1 = pi2 0.4 gives pi = (8, 4, 1) / 13. Eigenvalues 1 and
// (1.2 +- sqrt(0.12)) / 2 = 0.7732, 0.4268; 0.7732^60 = 2e-7, so a gap of 60 packets.
// loss = [0, 0.2, 0.9]; delays [0.6, 0.4] in state 0, [0.1, 0.3, 0.6] in state 1, none
// (delay 0) in state 2.
Eigen::MatrixXd birth_death() {
  Eigen::MatrixXd t(3, 3);
  t << 0.9, 0.1, 0.0, 0.2, 0.7, 0.1, 0.0, 0.4, 0.6;
  return t;
}
MarkovLink birth_death_link() {
  return MarkovLink(birth_death(), {0.0, 0.2, 0.9}, {{0.6, 0.4}, {0.1, 0.3, 0.6}, {}});
}
constexpr int kBirthDeathGap = 60;

// Gilbert–Elliott p_gb = 0.1, p_bg = 0.3: pi = (p_bg, p_gb) / (p_gb + p_bg) = (0.75, 0.25);
// second eigenvalue 1 - 0.1 - 0.3 = 0.6, 0.6^30 = 2.2e-7, so a gap of 30 packets.
constexpr int kGilbertGap = 30;

TEST(MarkovLink, StationaryLawSolvesTheBalanceEquations) {
  const MarkovLink chain = birth_death_link();
  ASSERT_EQ(chain.stationary().size(), 3);
  EXPECT_NEAR(chain.stationary()(0), 8.0 / 13.0, 1e-12);
  EXPECT_NEAR(chain.stationary()(1), 4.0 / 13.0, 1e-12);
  EXPECT_NEAR(chain.stationary()(2), 1.0 / 13.0, 1e-12);
  const auto ge = make_gilbert_elliott(0.1, 0.3, 0.0, 1.0);
  EXPECT_NEAR(ge->stationary()(0), 0.75, 1e-12);
  EXPECT_NEAR(ge->stationary()(1), 0.25, 1e-12);
  // Reducible chain (identity): every law is stationary; the solver returns a valid one.
  const MarkovLink frozen(Eigen::MatrixXd::Identity(2, 2), {0.0, 1.0});
  EXPECT_NEAR(frozen.stationary().sum(), 1.0, 1e-12);
  EXPECT_GE(frozen.stationary().minCoeff(), 0.0);
}

// delay_pmf = sum_s pi_s (1 - loss_s) pmf_s, with pi = (8, 4, 1) / 13:
//   state 0: 8/13 * 1.0 * [0.6, 0.4]        = [4.80, 3.20] / 13
//   state 1: 4/13 * 0.8 * [0.1, 0.3, 0.6]   = [0.32, 0.96, 1.92] / 13
//   state 2: 1/13 * 0.1 * [1]               = [0.10] / 13
//   total [5.22, 4.16, 1.92, 0] / 13; loss = (4 * 0.2 + 1 * 0.9) / 13 = 1.7 / 13.
// Gilbert–Elliott (0.1, 0.3, loss 0.01 / 0.8): loss = 0.75 * 0.01 + 0.25 * 0.8 = 0.2075,
// delay_pmf(1) = [0.7925, 0].
TEST(MarkovLink, DelayPmfAndLossMixTheStatesByTheStationaryLaw) {
  const MarkovLink chain = birth_death_link();
  ExpectVectorNear({5.22 / 13, 4.16 / 13, 1.92 / 13, 0.0}, chain.delay_pmf(3), 1e-12);
  ExpectVectorNear({5.22 / 13}, chain.delay_pmf(0), 1e-12);
  EXPECT_NEAR(chain.loss_probability(), 1.7 / 13, 1e-12);
  const auto ge = make_gilbert_elliott(0.1, 0.3, 0.01, 0.8);
  ExpectVectorNear({0.7925, 0.0}, ge->delay_pmf(1), 1e-12);
  EXPECT_NEAR(ge->loss_probability(), 0.2075, 1e-12);
}

// The birth–death link over 30000 * 60 packets, keeping every 60th: the state occupation
// fits (8, 4, 1) / 13 (chi-square, df = 2), the loss rate is within the bound around
// 1.7 / 13 = 0.130769, delivered delays fit [5.22, 4.16, 1.92] / 11.3 (df = 2).
TEST(MarkovLink, LongRunOccupationLossAndDelaysFollowTheStationaryLaw) {
  MarkovLink link = birth_death_link();
  Rng rng = stream(47);
  link.reset(rng);
  constexpr std::int64_t kN = 30000;
  std::vector<std::int64_t> occupation(3, 0);
  Tally t;
  t.delays.assign(3, 0);
  for (std::int64_t k = 0; k < kN; ++k) {
    for (int skip = 0; skip < kBirthDeathGap - 1; ++skip) link.transmit(rng);
    ++occupation[static_cast<std::size_t>(link.state())];
    const std::int64_t d = link.transmit(rng);
    ASSERT_GE(d, kLost);
    ASSERT_LE(d, 2);
    if (d == kLost) {
      ++t.lost;
    } else {
      ++t.delays[static_cast<std::size_t>(d)];
    }
  }
  EXPECT_TRUE(FitsDistribution("markov_occupation", occupation, {8.0 / 13, 4.0 / 13, 1.0 / 13}));
  EXPECT_TRUE(RateWithinBound("markov_loss", t.lost, kN, 1.7 / 13));
  EXPECT_TRUE(FitsDistribution("markov_delays", t.delays, {5.22 / 11.3, 4.16 / 11.3, 1.92 / 11.3}));
}

// reset() draws s_0 from the stationary law: over 20000 seeds the initial states fit
// (8, 4, 1) / 13 (df = 2), and the Gilbert–Elliott bad state has rate 0.25 +- 0.0101.
TEST(MarkovLink, ResetDrawsTheInitialStateFromTheStationaryLawAcrossSeeds) {
  constexpr std::int64_t kSeeds = 20000;
  MarkovLink chain = birth_death_link();
  const auto ge = make_gilbert_elliott(0.1, 0.3, 0.0, 1.0);
  std::vector<std::int64_t> initial(3, 0);
  std::int64_t bad = 0;
  for (std::int64_t seed = 0; seed < kSeeds; ++seed) {
    Rng a = kernel::make_stream(static_cast<std::uint64_t>(seed), 0,
                                kernel::stream_id(kernel::StreamKind::kLink, 0));
    chain.reset(a);
    ++initial[static_cast<std::size_t>(chain.state())];
    Rng b = kernel::make_stream(static_cast<std::uint64_t>(seed), 0,
                                kernel::stream_id(kernel::StreamKind::kLink, 1));
    ge->reset(b);
    bad += ge->state();
  }
  EXPECT_TRUE(FitsDistribution("markov_initial", initial, {8.0 / 13, 4.0 / 13, 1.0 / 13}));
  EXPECT_TRUE(RateWithinBound("gilbert_elliott_initial_bad", bad, kSeeds, 0.25));
}

// An explicit initial law replaces the stationary one: initial = (0, 1) always starts bad.
TEST(MarkovLink, ResetUsesTheGivenInitialLaw) {
  Eigen::MatrixXd t(2, 2);
  t << 0.9, 0.1, 0.3, 0.7;
  MarkovLink link(t, {0.0, 1.0}, {}, {0.0, 1.0});
  for (std::uint64_t seed = 0; seed < 200; ++seed) {
    Rng rng = stream(seed);
    link.reset(rng);
    ASSERT_EQ(link.state(), 1) << "seed " << seed;
    ASSERT_EQ(link.transmit(rng), kLost) << "seed " << seed;
  }
}

// Gilbert–Elliott with loss_good = 0, loss_bad = 1: a loss burst is a sojourn in the bad
// state, so its length L is Geometric(p_bad_to_good = 0.3): P[L = l] = 0.3 * 0.7^(l-1),
// mean 1 / 0.3 = 3.33. Good runs are Geometric(0.1). Sojourns are independent (strong
// Markov property), so over 10^6 packets (~75000 bursts; the first and last runs are
// dropped as censored) both fit by chi-square with pooled tails.
TEST(GilbertElliott, LossBurstLengthsAreGeometric) {
  const auto link = make_gilbert_elliott(0.1, 0.3, 0.0, 1.0);
  Rng rng = stream(53);
  link->reset(rng);
  constexpr std::int64_t kN = 1000000;
  constexpr std::size_t kMaxLen = 300;
  std::vector<std::int64_t> bursts(kMaxLen + 1, 0);  // index l - 1; last = longer
  std::vector<std::int64_t> gaps(kMaxLen + 1, 0);
  bool previous_lost = link->transmit(rng) == kLost;
  std::int64_t run = 1;
  bool first_run = true;
  for (std::int64_t k = 1; k < kN; ++k) {
    const bool lost = link->transmit(rng) == kLost;
    if (lost == previous_lost) {
      ++run;
      continue;
    }
    if (!first_run) {
      auto& hist = previous_lost ? bursts : gaps;
      ++hist[std::min<std::size_t>(static_cast<std::size_t>(run - 1), kMaxLen)];
    }
    first_run = false;
    previous_lost = lost;
    run = 1;
  }
  const auto geometric = [](double q) {
    std::vector<double> law;
    double s = 0.0;
    for (std::size_t l = 1; l <= kMaxLen; ++l) {
      law.push_back(q * std::pow(1.0 - q, static_cast<double>(l - 1)));
      s += law.back();
    }
    law.push_back(std::max(0.0, 1.0 - s));
    return law;
  };
  EXPECT_TRUE(FitsDistribution("gilbert_elliott_loss_bursts", bursts, geometric(0.3)));
  EXPECT_TRUE(FitsDistribution("gilbert_elliott_good_runs", gaps, geometric(0.1)));
}

// Gilbert–Elliott (0.1, 0.3, loss 0.01 / 0.8), 40000 packets kept one in 30: the bad-state
// rate within 0.25 +- 3.29 sqrt(0.1875 / 40000) = 0.25 +- 0.0071, the loss rate within
// 0.2075 +- 3.29 sqrt(0.2075 * 0.7925 / 40000) = 0.2075 +- 0.0067; every delay is 0.
TEST(GilbertElliott, LongRunOccupationAndLossRateFollowTheStationaryLaw) {
  const auto link = make_gilbert_elliott(0.1, 0.3, 0.01, 0.8);
  Rng rng = stream(59);
  link->reset(rng);
  constexpr std::int64_t kN = 40000;
  std::int64_t bad = 0;
  std::int64_t lost = 0;
  for (std::int64_t k = 0; k < kN; ++k) {
    for (int skip = 0; skip < kGilbertGap - 1; ++skip) link->transmit(rng);
    bad += link->state();
    const std::int64_t d = link->transmit(rng);
    ASSERT_TRUE(d == kLost || d == 0) << "delay " << d;
    lost += d == kLost;
  }
  EXPECT_TRUE(RateWithinBound("gilbert_elliott_bad_occupation", bad, kN, 0.25));
  EXPECT_TRUE(RateWithinBound("gilbert_elliott_loss", lost, kN, 0.2075));
}

// ---------------------------------------------------------------------------------------
// TraceLink and load_trace

// Trace [2, lost, 0, 5, lost]: delay_pmf(3) = [1, 0, 1, 0] / 5, loss = 2 / 5.
TEST(TraceLink, ReplaysExactlyAndRewindsOnReset) {
  TraceLink link({2, std::nullopt, 0, 5, std::nullopt});
  Rng rng = stream(61);
  const std::vector<std::int64_t> expected = {2, kLost, 0, 5, kLost};
  for (int pass = 0; pass < 3; ++pass) {
    link.reset(rng);
    for (std::size_t k = 0; k < expected.size(); ++k) {
      EXPECT_EQ(link.transmit(rng), expected[k]) << "pass " << pass << ", packet " << k;
    }
  }
  ExpectVectorNear({0.2, 0.0, 0.2, 0.0}, link.delay_pmf(3), 1e-15);
  EXPECT_DOUBLE_EQ(link.loss_probability(), 0.4);
  EXPECT_EQ(link.size(), 5u);
}

class TempFile {
 public:
  TempFile(const std::string& name, const std::string& content)
      : path_(std::filesystem::temp_directory_path() /
              ("ncosim_link_test_" + std::to_string(::getpid()) + "_" + name)) {
    std::ofstream out(path_, std::ios::binary);
    out << content;
  }
  ~TempFile() {
    std::error_code ec;
    std::filesystem::remove(path_, ec);
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  std::string path() const { return path_.string(); }

 private:
  std::filesystem::path path_;
};

// 20000 packets drawn from DelayPmfLink [0.45, 0.25, 0.12, 0.05, 0.001], written as a
// trace CSV and read back: the TraceLink replays the draws one for one, and its
// delay_pmf / loss_probability are the draws' empirical frequencies.
TEST(TraceLink, RoundTripThroughCsvReplaysTheDrawsAndTheirFrequencies) {
  DelayPmfLink source({0.45, 0.25, 0.12, 0.05, 0.001});
  Rng rng = stream(67);
  constexpr int kN = 20000;
  std::vector<std::int64_t> draws;
  std::ostringstream csv;
  csv << "seq,delay\n";
  std::vector<double> counts(6, 0.0);
  double lost = 0.0;
  for (int k = 0; k < kN; ++k) {
    draws.push_back(source.transmit(rng));
    csv << k << ",";
    if (draws.back() == kLost) {
      lost += 1.0;
    } else {
      csv << draws.back();
      counts[static_cast<std::size_t>(draws.back())] += 1.0;
    }
    csv << "\n";
  }
  const TempFile file("roundtrip.csv", csv.str());
  TraceLink trace(load_trace(file.path()));
  ASSERT_EQ(trace.size(), static_cast<std::size_t>(kN));
  for (int k = 0; k < kN; ++k) ASSERT_EQ(trace.transmit(rng), draws[k]) << "packet " << k;
  const std::vector<double> pmf = trace.delay_pmf(5);
  for (std::size_t d = 0; d < pmf.size(); ++d) {
    EXPECT_DOUBLE_EQ(pmf[d], counts[d] / kN) << "delay " << d;
  }
  EXPECT_DOUBLE_EQ(trace.loss_probability(), lost / kN);
}

// Header, lost entries (empty delay, also with blanks), CRLF line ends, spaces around
// fields and trailing blank lines are all accepted.
TEST(LoadTrace, ReadsHeaderLostEntriesCrlfAndTrailingBlankLines) {
  const TempFile file("good.csv", "seq,delay\r\n0,3\r\n1,\r\n2, 0\r\n3 , \r\n4,12\r\n\r\n\n");
  const auto trace = load_trace(file.path());
  const std::vector<std::optional<std::int64_t>> expected = {3, std::nullopt, 0, std::nullopt, 12};
  EXPECT_EQ(trace, expected);
  int first_row_line = 0;
  EXPECT_EQ(load_trace(file.path(), &first_row_line), expected);
  EXPECT_EQ(first_row_line, 2);                 // after the header
  const TempFile bare("bare.csv", "0,1\n1,0");  // no header, no final newline
  EXPECT_EQ(load_trace(bare.path(), &first_row_line),
            (std::vector<std::optional<std::int64_t>>{1, 0}));
  EXPECT_EQ(first_row_line, 1);
  const TempFile header_only("header_only.csv", "seq,delay\n");
  EXPECT_TRUE(load_trace(header_only.path()).empty());
}

std::optional<TraceError> trace_error(const std::string& path) {
  try {
    load_trace(path);
  } catch (const TraceError& e) {
    return e;
  }
  return std::nullopt;
}

TEST(LoadTrace, MissingFileThrowsAtLineZero) {
  const std::string path = (std::filesystem::temp_directory_path() /
                            ("ncosim_link_test_" + std::to_string(::getpid()) + "_absent.csv"))
                               .string();
  const auto error = trace_error(path);
  ASSERT_TRUE(error.has_value()) << "no TraceError for " << path;
  EXPECT_EQ(error->line, 0);
  EXPECT_EQ(error->file, path);
  EXPECT_NE(std::string(error->what()).find(path), std::string::npos) << error->what();
}

// Each malformed file and the line and message expected of it.
TEST(LoadTrace, MalformedLinesThrowWithTheirLineNumber) {
  struct Case {
    const char* name;
    const char* content;
    int line;
    const char* message;
  };
  const std::vector<Case> cases = {
      {"example", "x,1.5\n", 1,
       "expected 'seq,delay' with a non-negative integer delay, got 'x,1.5'"},
      {"fraction", "seq,delay\n0,1\n1,1.5\n", 3,
       "expected 'seq,delay' with a non-negative integer delay, got '1,1.5'"},
      {"negative", "0,1\n1,-1\n", 2,
       "expected 'seq,delay' with a non-negative integer delay, got '1,-1'"},
      {"word", "0,1\n1,2\n2,late\n", 3,
       "expected 'seq,delay' with a non-negative integer delay, got '2,late'"},
      {"skipped_seq", "seq,delay\n0,1\n2,1\n", 3,
       "expected 'seq,delay' with seq 1 (consecutive from 0), got '2,1'"},
      {"seq_not_from_zero", "1,4\n", 1,
       "expected 'seq,delay' with seq 0 (consecutive from 0), got '1,4'"},
      {"late_header", "0,1\nseq,delay\n", 2,
       "header 'seq,delay' is only allowed on the first line"},
      {"three_columns", "0,1\n1,2,3\n", 2,
       "expected 'seq,delay' (2 columns), got 3 columns in '1,2,3'"},
      {"one_column", "seq,delay\n0\n", 2, "expected 'seq,delay' (2 columns), got 1 column in '0'"},
      {"inner_blank", "0,1\n\n1,2\n", 2,
       "blank line inside the trace (only trailing blank lines are allowed)"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const TempFile file(std::string(c.name) + ".csv", c.content);
    const auto error = trace_error(file.path());
    ASSERT_TRUE(error.has_value()) << "no TraceError";
    EXPECT_EQ(error->file, file.path());
    EXPECT_EQ(error->line, c.line) << error->what();
    EXPECT_EQ(std::string(error->what()), c.message);
  }
}

// ---------------------------------------------------------------------------------------
// clone()

// For every kind: the clone of a used link (reset, 7 packets sent) has the same
// parameters, behaves draw for draw like a newly built link (no state carried over), and
// does not disturb the original, which continues like a twin that was never cloned.
TEST(LinkClone, GivesAFreshIndependentInstanceForEveryKind) {
  std::vector<std::optional<std::int64_t>> trace;
  for (int k = 0; k < 600; ++k) {
    trace.push_back(k % 5 == 3 ? std::nullopt : std::optional<std::int64_t>(k % 4));
  }
  const std::vector<std::pair<std::string, std::function<std::unique_ptr<Link>()>>> kinds = {
      {"delay",
       [] {
         return std::make_unique<DelayPmfLink>(std::vector<double>{0.3340, 0.3064});
       }},
      {"delay_independent",
       [] {
         return std::make_unique<DelayPmfLink>(std::vector<double>{0.3340, 0.3064}, true);
       }},
      {"bernoulli", [] { return std::make_unique<BernoulliLink>(0.3, 1); }},
      {"negative_binomial", [] { return std::make_unique<NegativeBinomialLink>(3, 0.5, 0.1); }},
      {"arrival_cdf",
       [] {
         return std::make_unique<ArrivalCdfLink>(std::vector<double>{0.1, 0.5}, 0.9);
       }},
      {"markov", [] { return std::make_unique<MarkovLink>(birth_death_link()); }},
      {"gilbert_elliott", [] { return make_gilbert_elliott(0.1, 0.3, 0.05, 0.9); }},
      {"trace", [trace] { return std::make_unique<TraceLink>(trace); }},
  };
  constexpr int kUsed = 7;
  constexpr int kCompared = 500;
  std::vector<std::int64_t> copies_a;
  std::vector<std::int64_t> copies_b;
  for (const auto& [name, make] : kinds) {
    SCOPED_TRACE(name);
    auto original = make();
    Rng r_original = stream(71);
    original->reset(r_original);
    for (int k = 0; k < kUsed; ++k) original->transmit(r_original);

    auto copy = original->clone();
    EXPECT_EQ(copy->delay_pmf(6), original->delay_pmf(6));
    EXPECT_EQ(copy->loss_probability(), original->loss_probability());

    auto fresh = make();
    Rng r_copy = stream(73);
    Rng r_fresh = stream(73);
    for (int k = 0; k < kCompared; ++k) {
      copy->transmit_copies(r_copy, copies_a);
      fresh->transmit_copies(r_fresh, copies_b);
      ASSERT_EQ(copies_a, copies_b) << "packet " << k << " of the clone vs a new link";
    }

    auto twin = make();
    Rng r_twin = stream(71);
    twin->reset(r_twin);
    for (int k = 0; k < kUsed; ++k) twin->transmit(r_twin);
    for (int k = 0; k < kCompared - kUsed; ++k) {
      ASSERT_EQ(original->transmit(r_original), twin->transmit(r_twin))
          << "packet " << kUsed + k << " of the original vs its uncloned twin";
    }
  }
}

}  // namespace
}  // namespace ncosim::models
