// tests/sim/consistency_test.cc — NEES/NIS averages against their chi-square bounds
// (sim/analysis/consistency.h) and the run-averaged error curve's sums (sim/run/error_curve.h).
#include "sim/analysis/consistency.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <boost/math/distributions/students_t.hpp>
#include <cmath>
#include <random>

#include "sim/run/error_curve.h"

namespace ncosim::sim {
namespace {

TEST(Consistency, NeesBoundsAreTheChiSquareQuantilesOfRunsTimesStates) {
  // 50 runs, n = 2: chi2(100) has 2.5 % and 97.5 % quantiles 74.2219 and 129.561 (tables).
  ConsistencySums s;
  s.nees = 2.0 * 50 * 300;
  s.nees_count = 50 * 300;
  s.nees_runs = 50;
  const auto st = nees_stat(s, 2);
  ASSERT_TRUE(st.has_value());
  EXPECT_DOUBLE_EQ(st->mean, 2.0);
  EXPECT_NEAR(st->lo, 74.2219 / 50, 1e-5);
  EXPECT_NEAR(st->hi, 129.561 / 50, 1e-5);
  EXPECT_TRUE(st->inside());
}

TEST(Consistency, NisBoundsAreTheChiSquareQuantilesOfTheSummedRows) {
  // 10 updates of one row each: chi2(10): 3.24697 and 20.4832.
  ConsistencySums s;
  s.nis = 25.0;
  s.nis_dof = 10;
  s.nis_count = 10;
  const auto st = nis_stat(s);
  ASSERT_TRUE(st.has_value());
  EXPECT_DOUBLE_EQ(st->mean, 2.5);
  EXPECT_NEAR(st->lo, 0.324697, 1e-6);
  EXPECT_NEAR(st->hi, 2.04832, 1e-5);
  EXPECT_FALSE(st->inside());
}

TEST(Consistency, NoteSaysWhichSideAndWhatItMeans) {
  EXPECT_EQ(consistency_note(std::nullopt, std::nullopt), "");
  const ConsistencyStat ok{2.0, 1.5, 2.5}, high{3.0, 1.5, 2.5}, low{1.0, 1.5, 2.5};
  EXPECT_EQ(consistency_note(ok, std::nullopt), "ok");
  EXPECT_EQ(consistency_note(ok, ok), "ok");
  EXPECT_EQ(consistency_note(high, ok),
            "NEES above its 95 % bound: the covariance is too small (overconfident)");
  EXPECT_EQ(consistency_note(std::nullopt, low),
            "NIS below its 95 % bound: the covariance is too large (pessimistic)");
  EXPECT_NE(consistency_note(high, low).find("; NIS below"), std::string::npos);
  ConsistencySums none;
  EXPECT_FALSE(nees_stat(none, 2).has_value());
  EXPECT_FALSE(nis_stat(none).has_value());
}

// The flagship's Kalman NIS (issue 40.6): 1.66918 just below [1.66995, 1.68302] printed as
// "NIS 1.669 in [1.67, 1.683]" (the word "in" for a value outside, digits that hide the order
// when closer). Now the digits show the order and the word says the side.
TEST(Consistency, StatTextHasTheDigitsAndTheWordOfItsSide) {
  const ConsistencyStat below{1.66918, 1.66995, 1.68302};
  EXPECT_EQ(consistency_stat_text("NIS", below), "NIS 1.669 below [1.670, 1.683]");
  const ConsistencyStat inside{2.005, 1.222, 2.967};
  EXPECT_EQ(consistency_stat_text("NEES", inside), "NEES 2.005 in [1.222, 2.967]");
  const ConsistencyStat above{2.9671, 1.222, 2.967};
  EXPECT_EQ(consistency_stat_text("NEES", above), "NEES 2.9671 above [1.2220, 2.9670]");
  // 1 part in 1e5 below: 4 digits would print both as 1.670.
  const ConsistencyStat close{1.66994, 1.66995, 1.68302};
  EXPECT_EQ(consistency_stat_text("NIS", close), "NIS 1.6699 below [1.6700, 1.6830]");
  const ConsistencyStat closer{1.669996, 1.669999, 1.68302};
  EXPECT_EQ(consistency_stat_text("NIS", closer), "NIS 1.669996 below [1.669999, 1.683020]");
  // Just inside: the printed value must not equal (or cross) the bound either.
  const ConsistencyStat edge{1.670000001, 1.67, 1.683};
  EXPECT_EQ(consistency_stat_text("NIS", edge), "NIS 1.670000001 in [1.670000000, 1.683000000]");
  const ConsistencyStat far_above{1e6, 0.5, 1.5};
  EXPECT_EQ(consistency_stat_text("NIS", far_above), "NIS 1.000e+06 above [0.5000, 1.500]");
  // The word agrees with inside() and consistency_note for every value.
  for (const double m : {1.66994, 1.66995, 1.67, 1.683, 1.68302, 1.68303}) {
    const ConsistencyStat s{m, 1.66995, 1.68302};
    const std::string text = consistency_stat_text("NIS", s);
    EXPECT_EQ(text.find(" in ") != std::string::npos, s.inside()) << text;
  }
}

void add(ErrorCurve& c, std::int64_t k, std::size_t e, const Eigen::VectorXd& err) {
  c.add(k, e, err.data());
}

TEST(ErrorCurve, MeanBandAndStatesOfKnownErrors) {
  ErrorCurve c(2, 1, 2);
  const std::vector<Eigen::Vector2d> errs{{1.0, 0.0}, {0.0, 2.0}, {1.0, 1.0}};  // |e|^2 = 1, 4, 2
  for (std::size_t r = 0; r < errs.size(); ++r) {
    add(c, 0, 0, errs[r]);
    add(c, 1, 0, 2.0 * errs[r]);
    c.add_run(r);
  }
  EXPECT_DOUBLE_EQ(c.mean(0, 0), 7.0 / 3.0);
  EXPECT_DOUBLE_EQ(c.mean_state(0, 0, 0), 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(c.mean_state(0, 0, 1), 5.0 / 3.0);
  EXPECT_DOUBLE_EQ(c.mean(1, 0), 28.0 / 3.0);
  const double m = 7.0 / 3.0;
  const double sd = std::sqrt(((1 - m) * (1 - m) + (4 - m) * (4 - m) + (2 - m) * (2 - m)) / 2.0);
  const double t =
      boost::math::quantile(boost::math::complement(boost::math::students_t(2.0), 0.025));
  EXPECT_NEAR(c.ci95(0, 0), t * sd / std::sqrt(3.0), 1e-12);
  // Every run with the same error (an exact start): no spread, a band of exactly 0.
  ErrorCurve same(1, 1, 2);
  for (std::size_t r = 0; r < 7; ++r) {
    add(same, 0, 0, Eigen::Vector2d(0.1, 0.3));
    same.add_run(r);
  }
  EXPECT_EQ(same.ci95(0, 0), 0.0);
  ErrorCurve one(1, 1, 1);
  add(one, 0, 0, Eigen::VectorXd::Ones(1));
  one.add_run(0);
  EXPECT_TRUE(std::isnan(one.ci95(0, 0)));  // one run: no band
}

// The means must not depend on which thread, session or shard added which run: the same runs
// added in run order, in reverse, and in three interleaved parts merged give the same bits,
// where a plain double sum (checked here too) differs.
TEST(ErrorCurve, MeansDoNotDependOnTheOrderOrPartitionOfTheRuns) {
  constexpr std::int64_t kPeriods = 50;
  constexpr std::size_t kRuns = 400;
  std::mt19937_64 rng(5);
  std::lognormal_distribution<double> mag(0.0, 6.0);  // magnitudes over many decades
  std::vector<Eigen::MatrixXd> errs;                  // per run: n x periods
  for (std::size_t r = 0; r < kRuns; ++r) {
    Eigen::MatrixXd e(2, kPeriods);
    for (Eigen::Index i = 0; i < e.size(); ++i) e.data()[i] = mag(rng);
    errs.push_back(e);
  }
  auto add = [&](ErrorCurve& c, std::size_t r) {
    for (std::int64_t k = 0; k < kPeriods; ++k) ncosim::sim::add(c, k, 0, errs[r].col(k));
    c.add_run(r);
  };
  ErrorCurve forward(kPeriods, 1, 2), backward(kPeriods, 1, 2), merged(kPeriods, 1, 2);
  for (std::size_t r = 0; r < kRuns; ++r) add(forward, r);
  for (std::size_t r = kRuns; r-- > 0;) add(backward, r);
  std::vector<ErrorCurve> parts(3, ErrorCurve(kPeriods, 1, 2));
  for (std::size_t r = 0; r < kRuns; ++r) add(parts[(r * 7) % 3], r);
  for (std::size_t p = 3; p-- > 0;) merged.merge(parts[p]);
  int naive_differs = 0;
  for (std::int64_t k = 0; k < kPeriods; ++k) {
    ASSERT_EQ(forward.mean(k, 0), backward.mean(k, 0)) << "k = " << k;
    ASSERT_EQ(forward.mean(k, 0), merged.mean(k, 0)) << "k = " << k;
    ASSERT_EQ(forward.ci95(k, 0), merged.ci95(k, 0)) << "k = " << k;
    double f = 0.0, b = 0.0;
    for (std::size_t r = 0; r < kRuns; ++r) f += errs[r](0, k) * errs[r](0, k);
    for (std::size_t r = kRuns; r-- > 0;) b += errs[r](0, k) * errs[r](0, k);
    naive_differs += f != b;
  }
  EXPECT_GT(naive_differs, 0) << "the data do not exercise rounding (the test could not fail)";
  EXPECT_EQ(merged.runs().size(), kRuns);
}

TEST(ErrorCurve, SerializesExactlyAndRejectsDamagedRecords) {
  ErrorCurve c(3, 2, 2);
  add(c, 2, 1, Eigen::Vector2d(0.1, 1e-300));
  add(c, 0, 0, Eigen::Vector2d(3.0, std::nan("")));
  c.add_run(9);
  const std::string blob = c.serialize();
  const ErrorCurve d = ErrorCurve::deserialize(blob);
  EXPECT_EQ(d.serialize(), blob);
  EXPECT_EQ(d.runs(), std::vector<std::uint64_t>{9});
  EXPECT_THROW(ErrorCurve::deserialize(blob.substr(0, blob.size() - 1)), std::runtime_error);
  EXPECT_THROW(ErrorCurve::deserialize(blob.substr(0, 20)), std::runtime_error);
  std::string huge = blob;
  huge[8] = '\xff';  // periods: far more than the record holds
  EXPECT_THROW(ErrorCurve::deserialize(huge), std::runtime_error);
  EXPECT_THROW(ErrorCurve::deserialize(""), std::runtime_error);
}

}  // namespace
}  // namespace ncosim::sim
