// tests/sim/paired_test.cc — paired and Welch differences, Holm, the [paired] table.
#include "sim/analysis/paired.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "sim/analysis/output.h"
#include "sim/run/campaign.h"
#include "test_util.h"

namespace ncosim::sim {
namespace {

TEST(Paired, DifferenceAndRatioByHand) {
  // d = (1, 2, 2): mean 5/3, s^2 = 1/3, se = 1/3, t_{0.975,2} = 4.302653 -> half 1.434218.
  // R = (11/3) / 2 = 1.833333; z = (fresh - R base) / 2 = (1/12, 1/6, -1/4): s^2 = 0.0486111,
  // se = 0.1272938 -> half 0.5477009.
  const auto d = paired_difference({1, 2, 3}, {2, 4, 5});
  ASSERT_TRUE(d);
  EXPECT_TRUE(d->paired);
  EXPECT_NEAR(d->diff, 5.0 / 3.0, 1e-12);
  EXPECT_NEAR(*d->diff_half, 1.434218, 1e-6);
  EXPECT_NEAR(*d->ratio, 11.0 / 6.0, 1e-12);
  EXPECT_NEAR(*d->ratio_half, 0.5477009, 1e-6);
  EXPECT_DOUBLE_EQ(d->dof, 2.0);
  EXPECT_FALSE(paired_difference({1, 2}, {1, 2, 3}));  // not paired
  EXPECT_FALSE(paired_difference({1}, {1}));           // one run: no interval
  EXPECT_FALSE(paired_difference({1, NAN}, {1, 2}));
}

TEST(Paired, WelchByHand) {
  // var 1 and 4 over 3 values each: se^2 = 1/3 + 4/3, dof = (5/3)^2 / ((1/3)^2/2 + (4/3)^2/2)
  // = 2.941176; t_{0.975, 2.941176} = 3.2305 (boost), half = t * 1.290994.
  const auto d = welch_difference({1, 2, 3}, {2, 4, 6});
  ASSERT_TRUE(d);
  EXPECT_FALSE(d->paired);
  EXPECT_NEAR(d->diff, 2.0, 1e-12);
  EXPECT_NEAR(d->dof, 2.941176, 1e-6);
  EXPECT_NEAR(*d->diff_half, t_two_sided(d->dof, 0.95) * std::sqrt(5.0 / 3.0), 1e-12);
  EXPECT_NEAR(*d->ratio, 2.0, 1e-12);
}

TEST(Paired, HolmStepDownByHand) {
  // Sorted 0.01, 0.03, 0.04, 0.5 times 4, 3, 2, 1 = 0.04, 0.09, 0.08, 0.5; running maximum.
  const auto adj = holm_adjust({0.01, 0.04, 0.03, 0.5});
  ASSERT_EQ(adj.size(), 4u);
  EXPECT_NEAR(adj[0], 0.04, 1e-15);
  EXPECT_NEAR(adj[1], 0.09, 1e-15);
  EXPECT_NEAR(adj[2], 0.09, 1e-15);
  EXPECT_NEAR(adj[3], 0.5, 1e-15);
}

TEST(Paired, RelativeTestEqualDataIsNeverSignificant) {
  const std::vector<double> a{1.0, 1.1, 0.9, 1.05};
  const auto t = relative_test(a, a, true, 0.0);
  EXPECT_EQ(t.p_worse, 1.0);
  EXPECT_EQ(t.p_better, 1.0);
  // +10 % on every run: e = 0.1 a, mean 0.10125, sd 0.00854, t = 23.7 on 3 dof (p = 8.2e-5):
  // worse at margin 0; not worse beyond a 20 % margin.
  std::vector<double> b = a;
  for (double& x : b) x *= 1.1;
  EXPECT_NEAR(relative_test(a, b, true, 0.0).p_worse, 8.2e-5, 0.1e-5);
  EXPECT_GT(relative_test(a, b, true, 0.2).p_worse, 0.5);
}

TEST(Paired, HolmKeepsTheFamilyWiseErrorOfTheWorseTests) {
  // 2000 families of 6 rows with no change (base and new from the same law, paired runs with a
  // shared run effect, as in a campaign): the share of families with any row "worse" at
  // alpha = 0.05 after Holm must not exceed 5 % beyond binomial noise (99.9 % upper bound of
  // Binomial(2000, 0.05) is 126). Without the correction it is about 1 - 0.95^6 = 26.5 %, which
  // the same bound must catch (the test can fail).
  std::mt19937_64 gen(14);
  std::normal_distribution<double> z;
  const int families = 2000, rows = 6, runs = 20;
  int holm_errors = 0, raw_errors = 0;
  for (int f = 0; f < families; ++f) {
    std::vector<double> p;
    for (int r = 0; r < rows; ++r) {
      std::vector<double> a(runs), b(runs);
      for (int i = 0; i < runs; ++i) {
        const double shared = 1.0 + 0.1 * z(gen);
        a[static_cast<std::size_t>(i)] = shared + 0.01 * z(gen);
        b[static_cast<std::size_t>(i)] = shared + 0.01 * z(gen);
      }
      p.push_back(relative_test(a, b, true, 0.0).p_worse);
    }
    const auto adj = holm_adjust(p);
    holm_errors += std::any_of(adj.begin(), adj.end(), [](double x) { return x <= 0.05; });
    raw_errors += std::any_of(p.begin(), p.end(), [](double x) { return x <= 0.05; });
  }
  std::printf("families with a false 'worse': Holm %d, uncorrected %d of %d (bound 126)\n",
              holm_errors, raw_errors, families);
  EXPECT_LE(holm_errors, 126);
  EXPECT_GT(raw_errors, 126);
}

std::string write_temp(const std::string& name, const std::string& text) {
  const auto p = std::filesystem::temp_directory_path() / name;
  std::ofstream(p) << text;
  return p.string();
}

constexpr const char* kSwept = R"(title = "paired keys"
[run]
periods = 200
runs = 4
[plant]
A = [[0.8]]
W = [[1.0]]
[[sensor]]
C = [[1.0]]
R = [[1.0]]
link = "net"
[[link]]
name = "net"
kind = "bernoulli"
loss = 0.1
[[estimator]]
name = "ol"
kind = "open_loop"
[[estimator]]
name = "kf"
kind = "kalman_extended"
[[sweep]]
key = "link[0].loss"
values = [0.1, 0.5]
[[sweep]]
key = "plant.W"
values = [1.0, 2.0]
)";

TEST(Paired, DefaultReferenceIsTheFirstKalmanTypeRowAndTheFirstCase) {
  const std::string f = write_temp("ncosim_paired_keys.toml", kSwept);
  const auto loaded = load_cases(f, {});
  EXPECT_EQ(reference_estimator_index(*loaded.cases[0].scenario), 1u);
  EXPECT_EQ(reference_case_index(loaded), 0u);
  const auto named =
      load_cases(f, {"paired.reference=\"ol\"", "paired.reference_case={\"plant.W\" = 2.0}"});
  EXPECT_EQ(reference_estimator_index(*named.cases[0].scenario), 0u);
  EXPECT_EQ(reference_case_index(named), 1u);  // loss 0.1 (first value), W = 2
  const auto both =
      load_cases(f, {"paired.reference_case={\"plant.W\" = 2.0, \"link[0].loss\" = 0.5}"});
  EXPECT_EQ(reference_case_index(both), 3u);
  std::filesystem::remove(f);
}

TEST(Paired, BadKeysNameTheKeyAndTheValidValues) {
  const std::string f = write_temp("ncosim_paired_bad.toml", kSwept);
  auto message = [&](const std::vector<std::string>& sets) {
    try {
      const auto loaded = load_cases(f, sets);
      reference_case_index(loaded);
    } catch (const config::ScenarioError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string ref = message({"paired.reference=\"KF\""});
  EXPECT_NE(
      ref.find("key 'paired.reference': expected an estimator name (\"ol\", \"kf\"), got \"KF\""),
      std::string::npos)
      << ref;
  const std::string key = message({"paired.reference_case={\"plant.w\" = 2.0}"});
  EXPECT_NE(key.find("key 'paired.reference_case': expected a swept key path"), std::string::npos)
      << key;
  EXPECT_NE(key.find("did you mean \"plant.W\""), std::string::npos) << key;
  const std::string value = message({"paired.reference_case={\"plant.W\" = 3.0}"});
  EXPECT_NE(value.find("expected one of the values of \"plant.W\" (1.0, 2.0), got 3.0"),
            std::string::npos)
      << value;
  const std::string unknown = message({"paired.refrence=\"kf\""});
  EXPECT_NE(unknown.find("paired.refrence"), std::string::npos) << unknown;
  std::filesystem::remove(f);
}

TEST(Paired, SummaryColumnsWithinAndAcrossCases) {
  // Every case pairs with the Kalman row of its case; across cases every row pairs with the same
  // estimator of case 0. The reference rows have empty paired cells.
  const std::string f = write_temp("ncosim_paired_rows.toml", kSwept);
  const auto loaded = load_cases(f, {});
  std::filesystem::remove(f);
  std::vector<SummaryRow> rows;
  CampaignOptions opt;
  opt.time_estimators = false;
  for (const auto& c : loaded.cases) {
    const CampaignResult r = run_campaign(*c.scenario, opt);
    auto case_rows = summarise(*c.scenario, r, c.labels);
    rows.insert(rows.end(), case_rows.begin(), case_rows.end());
  }
  add_paired_across_cases(rows, loaded, reference_case_index(loaded));
  ASSERT_EQ(rows.size(), 8u);
  EXPECT_EQ(rows[0].paired.reference, "kf");
  EXPECT_FALSE(rows[1].paired.mse.diff);  // the reference itself
  ASSERT_TRUE(rows[0].paired.mse.diff);   // open loop minus Kalman, same runs
  double d = 0.0;
  for (std::size_t i = 0; i < 4; ++i) d += rows[0].per_run.mse[i] - rows[1].per_run.mse[i];
  EXPECT_NEAR(*rows[0].paired.mse.diff, d / 4.0, 1e-12);
  EXPECT_NEAR(*rows[0].paired.mse.ratio, *rows[0].mse / *rows[1].mse, 1e-12);
  EXPECT_FALSE(rows[0].paired.case_mse.diff);  // case 0 is the reference case
  ASSERT_TRUE(rows[7].paired.case_mse.diff);   // kf at loss 0.5, W = 2 vs kf in case 0
  EXPECT_NEAR(*rows[7].paired.case_mse.diff, *rows[7].mse - *rows[1].mse, 1e-12);
  EXPECT_EQ(rows[7].paired.reference_case, "link[0].loss=0.1; plant.W=1.0");
  const auto cols = paired_column_names(true);
  EXPECT_EQ(paired_cells(rows[7].paired, true).size(), cols.size());
  EXPECT_EQ(cols.front(), "paired_reference");
  EXPECT_EQ(paired_column_names(false).size(), 13u);
}

// Issue 40.8: the default reference was the first Kalman-type row whatever its run (the
// pendulum's "optimal N=1", which diverges), and every paired column came out empty without a
// word. A Kalman filter with a one-period buffer never gets a sample here (every packet is at
// least one period late) and diverges on the unstable plant; the default must skip it.
constexpr const char* kDivergingKalman = R"(title = "a Kalman reference that diverges"
[run]
periods = 400
runs = 4
[plant]
A = [[2.0]]
W = [[1.0]]
[[sensor]]
C = [[1.0]]
R = [[1.0]]
link = "net"
[[link]]
name = "net"
kind = "arrival_cdf"
cdf = [0.0, 0.9]
tail = 0.9
[[estimator]]
name = "static N=2"
kind = "static_buffer"
buffer = 2
[[estimator]]
name = "optimal N=1"
kind = "kalman_buffer"
buffer = 1
[[estimator]]
name = "optimal N=2"
kind = "kalman_buffer"
buffer = 2
)";

TEST(Paired, DefaultReferenceIsARowWhoseRunsAreOk) {
  const std::string f = write_temp("ncosim_paired_diverging.toml", kDivergingKalman);
  const auto loaded = load_cases(f, {});
  const auto named = load_cases(f, {"paired.reference=\"optimal N=1\""});
  std::filesystem::remove(f);
  CampaignOptions opt;
  opt.time_estimators = false;
  const Scenario& sc = *loaded.cases[0].scenario;
  const auto rows = summarise(sc, run_campaign(sc, opt), {});
  ASSERT_EQ(rows.size(), 3u);
  ASSERT_EQ(rows[1].status, "diverged");
  ASSERT_EQ(rows[2].status, "ok");
  EXPECT_EQ(reference_estimator_index(sc), 1u);  // the first Kalman-type row, before the runs
  EXPECT_EQ(reference_row_index(sc, rows), 2u);  // the first Kalman-type row whose runs are ok
  for (const auto& r : rows) EXPECT_EQ(r.paired.reference, "optimal N=2");
  EXPECT_TRUE(rows[0].paired.mse.diff.has_value());  // static N=2 minus optimal N=2
  EXPECT_EQ(paired_reference_note(rows), "");
  // Without an ok Kalman row: the first ok row; without any: the first Kalman-type row.
  std::vector<SummaryRow> no_kalman = rows;
  no_kalman[0].status = "ok";
  no_kalman[2].status = "heavy_tail";
  EXPECT_EQ(reference_row_index(sc, no_kalman), 0u);
  no_kalman[0].status = "diverged";
  EXPECT_EQ(reference_row_index(sc, no_kalman), 1u);
  // A reference the user names is kept whatever its status, and the note says why the
  // columns are empty.
  const Scenario& nsc = *named.cases[0].scenario;
  const auto nrows = summarise(nsc, run_campaign(nsc, opt), {});
  EXPECT_EQ(nrows[0].paired.reference, "optimal N=1");
  EXPECT_FALSE(nrows[0].paired.mse.diff.has_value());
  const std::string note = paired_reference_note(nrows);
  EXPECT_NE(note.find("The reference \"optimal N=1\" has status diverged: no per-run mse to pair "
                      "with, so its case's paired columns are empty."),
            std::string::npos)
      << note;
  EXPECT_NE(summary_markdown("t", {}, nrows, 1).find(note), std::string::npos);
}

}  // namespace
}  // namespace ncosim::sim
