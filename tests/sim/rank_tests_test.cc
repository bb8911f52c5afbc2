// tests/sim/rank_tests_test.cc — the signed-rank and rank-sum null laws against enumeration, the
// Hodges–Lehmann order statistics against sorting every shift value, and the interval as the
// inversion of the test (sim/analysis/rank_tests.h).
#include "sim/analysis/rank_tests.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace ncosim::sim {
namespace {

// P(S >= c) by enumerating every sign pattern (signed-rank) of n ranks.
std::vector<double> signed_rank_by_enumeration(std::size_t n) {
  const std::size_t top = n * (n + 1) / 2;
  std::vector<double> count(top + 2, 0.0);
  for (std::uint64_t mask = 0; mask < (std::uint64_t{1} << n); ++mask) {
    std::size_t s = 0;
    for (std::size_t k = 0; k < n; ++k) s += (mask >> k & 1U) != 0 ? k + 1 : 0;
    count[s] += 1.0;
  }
  std::vector<double> tail(top + 2, 0.0);
  for (std::size_t c = top + 1; c-- > 0;) tail[c] = tail[c + 1] + count[c];
  for (double& t : tail) t /= std::pow(2.0, static_cast<double>(n));
  return tail;
}

// P(U >= c) by enumerating which of the m + n positions hold the second sample.
std::vector<double> rank_sum_by_enumeration(std::size_t m, std::size_t n) {
  const std::size_t total = m + n;
  std::vector<double> count(m * n + 2, 0.0);
  double all = 0.0;
  for (std::uint64_t mask = 0; mask < (std::uint64_t{1} << total); ++mask) {
    if (static_cast<std::size_t>(__builtin_popcountll(mask)) != n) continue;
    // U: pairs (x, y) with y above x.
    std::size_t u = 0, xs = 0;
    for (std::size_t e = 0; e < total; ++e) {
      if ((mask >> e & 1U) != 0) {
        u += xs;
      } else {
        ++xs;
      }
    }
    count[u] += 1.0;
    all += 1.0;
  }
  std::vector<double> tail(m * n + 2, 0.0);
  for (std::size_t c = m * n + 1; c-- > 0;) tail[c] = tail[c + 1] + count[c];
  for (double& t : tail) t /= all;
  return tail;
}

TEST(RankTests, SignedRankNullIsTheEnumeratedLaw) {
  for (std::size_t n = 1; n <= 14; ++n) {
    const RankNull law = RankNull::signed_rank(n);
    ASSERT_TRUE(law.exact());
    ASSERT_EQ(law.max(), n * (n + 1) / 2);
    const auto tail = signed_rank_by_enumeration(n);
    for (std::size_t c = 0; c <= law.max() + 1; ++c)
      EXPECT_NEAR(law.upper_tail(c), tail[c], 1e-14) << "n " << n << " c " << c;
  }
  // A table value: n = 10, P(W+ <= 10) = P(W+ >= 45) = 43 / 1024.
  EXPECT_NEAR(RankNull::signed_rank(10).upper_tail(45), 43.0 / 1024.0, 1e-15);
  EXPECT_EQ(RankNull::signed_rank(10).critical(0.05), 45u);  // 0.0420 <= 0.05 < P(W+ >= 44)
}

TEST(RankTests, RankSumNullIsTheEnumeratedLaw) {
  for (std::size_t m = 1; m <= 7; ++m) {
    for (std::size_t n = 1; n <= 8; ++n) {
      const RankNull law = RankNull::rank_sum(m, n);
      ASSERT_TRUE(law.exact());
      const auto tail = rank_sum_by_enumeration(m, n);
      for (std::size_t c = 0; c <= m * n + 1; ++c)
        EXPECT_NEAR(law.upper_tail(c), tail[c], 1e-14) << m << "x" << n << " c " << c;
    }
  }
}

TEST(RankTests, NormalApproximationBeyondTheExactRangeIsClose) {
  // The exact law at n = 200 against the normal one at 201 scaled to it: the critical counts at
  // the levels compare uses differ by less than 0.5 % of the mean.
  const RankNull exact = RankNull::signed_rank(200), approx = RankNull::signed_rank(201);
  ASSERT_TRUE(exact.exact());
  ASSERT_FALSE(approx.exact());
  for (const double a : {0.05, 0.01, 0.001}) {
    const double ce = static_cast<double>(exact.critical(a)) / (200.0 * 201.0 / 4.0);
    const double ca = static_cast<double>(approx.critical(a)) / (201.0 * 202.0 / 4.0);
    EXPECT_NEAR(ce, ca, 0.005) << a;
  }
  const RankNull big = RankNull::rank_sum(60, 70);
  ASSERT_FALSE(big.exact());
  EXPECT_NEAR(big.upper_tail(2100),
              0.5 * std::erfc((2100 - 0.5 - 2100) / std::sqrt(2.0 * 60 * 70 * 131 / 12.0)), 1e-15);
  // Monotone, 1 at 0 and 0 past the end, whichever law.
  for (const auto& law : {big, approx, RankNull::rank_sum(3, 4)}) {
    EXPECT_EQ(law.upper_tail(0), 1.0);
    EXPECT_EQ(law.upper_tail(law.max() + 1), 0.0);
    for (std::size_t c = 1; c <= law.max(); c += 7)
      EXPECT_LE(law.upper_tail(c), law.upper_tail(c - 1));
  }
}

// Every shift value, sorted.
std::vector<double> all_walsh(const std::vector<double>& d) {
  std::vector<double> w;
  for (std::size_t i = 0; i < d.size(); ++i)
    for (std::size_t j = i; j < d.size(); ++j) w.push_back((d[i] + d[j]) * 0.5);
  std::sort(w.begin(), w.end());
  return w;
}
std::vector<double> all_differences(const std::vector<double>& x, const std::vector<double>& y) {
  std::vector<double> w;
  for (double a : x)
    for (double b : y) w.push_back(b - a);
  std::sort(w.begin(), w.end());
  return w;
}

// Checks kth, above, below and median of `s` against the sorted values `w`, and that each bound
// excludes t exactly when the p-value against t is at most the level.
void expect_matches(const ShiftValues& s, const std::vector<double>& w) {
  ASSERT_EQ(s.count(), w.size());
  for (std::size_t k = 1; k <= w.size(); ++k) ASSERT_EQ(s.kth(k), w[k - 1] + 0.0) << k;
  const std::size_t n = w.size();
  EXPECT_EQ(s.median(), n % 2 ? w[n / 2] : w[n / 2 - 1] + (w[n / 2] - w[n / 2 - 1]) / 2.0);
  std::vector<double> probes = w;
  probes.push_back(w.front() - 1.0);
  probes.push_back(w.back() + 1.0);
  for (std::size_t i = 0; i + 1 < w.size(); i += 3) probes.push_back((w[i] + w[i + 1]) / 2.0);
  for (const double t : probes) {
    const auto above = static_cast<std::size_t>(
        std::count_if(w.begin(), w.end(), [t](double v) { return v > t; }));
    const auto below = static_cast<std::size_t>(
        std::count_if(w.begin(), w.end(), [t](double v) { return v < t; }));
    ASSERT_EQ(s.above(t), above) << t;
    ASSERT_EQ(s.below(t), below) << t;
    for (const double a : {0.2, 0.05, 0.01, 0.001}) {
      EXPECT_EQ(s.lower(a) > t, s.p_above(t) <= a) << t << " " << a;
      EXPECT_EQ(s.upper(a) < t, s.p_below(t) <= a) << t << " " << a;
    }
  }
}

TEST(RankTests, OrderStatisticsAndCountsMatchEveryShiftValueSorted) {
  std::mt19937_64 g(11);
  std::student_t_distribution<double> heavy(1.5);
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<double> d(5 + trial);
    for (auto& v : d) v = std::round(heavy(g) * 4.0) / 4.0;  // ties on purpose
    expect_matches(ShiftValues::walsh(d), all_walsh(d));
    std::vector<double> x(3 + trial % 7), y(4 + trial);
    for (auto& v : x) v = std::round(heavy(g) * 4.0) / 4.0;
    for (auto& v : y) v = heavy(g) + 0.5;
    expect_matches(ShiftValues::differences(x, y), all_differences(x, y));
  }
  // All equal: every shift value is 0, the interval [0, 0] once the runs suffice.
  const auto zero = ShiftValues::walsh(std::vector<double>(8, 0.0));
  EXPECT_EQ(zero.median(), 0.0);
  EXPECT_EQ(zero.lower(0.05), 0.0);
  EXPECT_EQ(zero.upper(0.05), 0.0);
  // Too few for the level: P(W+ = N) = 2^-3 > 0.05, no bound.
  const auto few = ShiftValues::walsh({1.0, 2.0, 3.0});
  EXPECT_EQ(few.lower(0.05), -std::numeric_limits<double>::infinity());
  EXPECT_EQ(few.upper(0.05), std::numeric_limits<double>::infinity());
  EXPECT_EQ(few.p_above(0.0), 0.125);
}

TEST(RankTests, LargeSamplesNeedNoStoreOfTheShiftValues) {
  // 3000 pairs: 4.5 million Walsh averages, found by counting; the median of d + 1 is the
  // median's + 1 exactly when the shift is a power of two.
  std::mt19937_64 g(3);
  std::normal_distribution<double> z;
  std::vector<double> d(3000), e(3000);
  for (std::size_t i = 0; i < d.size(); ++i) {
    d[i] = z(g);
    e[i] = d[i] + 1.0;
  }
  const auto a = ShiftValues::walsh(d), b = ShiftValues::walsh(e);
  EXPECT_NEAR(b.median() - a.median(), 1.0, 1e-12);
  EXPECT_LT(a.lower(0.05), a.median());
  EXPECT_GT(a.upper(0.05), a.median());
  EXPECT_NEAR(a.upper(0.05) - a.lower(0.05), 2 * 1.645 * std::sqrt(M_PI / 3.0 / 3000.0), 0.01);
}

}  // namespace
}  // namespace ncosim::sim
