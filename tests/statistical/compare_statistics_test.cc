// tests/statistical/compare_statistics_test.cc — `ncosim compare` as a CI gate on the flagship
// (Dolz et al. 2014, Table 2; 20 runs x 20000 periods): an injected regression of one row is
// flagged at every one of 20 seeds (small ones at a 0.2 % tolerance; issue 40's Kalman filter with
// max_delay = 0, heavy-tailed, at the default 5 %), an unchanged build is not, and campaigns of
// other seeds are shown unchanged with enough runs and inconclusive with too few.
#include <gtest/gtest.h>

#include <algorithm>
#include <boost/math/distributions/binomial.hpp>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "sim/analysis/compare.h"
#include "sim/analysis/paired.h"
#include "sim/run/campaign.h"
#include "test_util.h"

namespace ncosim::sim {
namespace {

using testing::read_text;
using testing::source_path;

// The flagship with extra rows on the same realisation: "S1, 1 gain" designed by the paper's LMI
// method (`design = "ccl"`, about 0.75 % lower MSE than the iterative gains of the flagship row),
// and "S4, 60 gains" redesigned with history 2 and 3 instead of 4 (fewer stored gains). Each
// is a realistic regression of one row: NEW = iterative S1 against BASE = CCL S1 (+0.75 %),
// NEW = S4 with history 2 (+1.9 %) or 3 (+0.25 %) against the flagship's S4. Every estimator sees
// the same realisation, so a row swapped in this way is exactly what a separate campaign at the
// same seed would write.
std::unique_ptr<Scenario> flagship_with_variants() {
  std::string text = read_text(source_path("scenarios/dolz2014_table2.toml"));
  for (int h : {2, 3}) {
    text += "\n[[estimator]]\nname = \"S4 h" + std::to_string(h) +
            "\"\nkind = \"jump\"\ngrouping = \"S4\"\nhistory = " + std::to_string(h) +
            "\nmax_delay = 1\n";
  }
  text +=
      "\n[[estimator]]\nname = \"S1 ccl\"\nkind = \"jump\"\ngrouping = \"S1\"\nhistory = "
      "1\nmax_delay = 1\n"
      "design = \"ccl\"\n";
  // What `--set estimator[5].max_delay=0` makes of the Kalman row: it ignores every late sample.
  text += "\n[[estimator]]\nname = \"Kalman md0\"\nkind = \"kalman_extended\"\nmax_delay = 0\n";
  const auto p = std::filesystem::temp_directory_path() / "ncosim_compare_flagship.toml";
  std::ofstream(p) << text;
  auto sc = testing::load_one(p.string());
  std::filesystem::remove(p);
  return sc;
}

// A run folder as read_run_folder() would give for the 7 flagship rows; the row named `row`
// takes its values from the estimator `from`.
RunFolder folder(const Scenario& sc, const CampaignResult& r, std::uint64_t seed,
                 const std::string& row_name = "", const std::string& from = "") {
  RunFolder f;
  f.dir = "seed" + std::to_string(seed);
  f.scenario = "scenarios/dolz2014_table2.toml";
  f.scenario_hash = "flagship";
  f.seed = seed;
  for (std::size_t e = 0; e < 7; ++e) {
    std::size_t src = e;
    if (sc.estimators[e].name == row_name) {
      for (std::size_t j = 0; j < sc.estimators.size(); ++j) {
        if (sc.estimators[j].name == from) src = j;
      }
    }
    RunFolder::Row row;
    row.estimator = sc.estimators[e].name;
    for (std::size_t run = 0; run < r.runs.size(); ++run) {
      const auto& m = r.runs[run][src];
      row.run.push_back(static_cast<std::int64_t>(run));
      row.diverged.push_back(m.diverged);
      row.value.push_back(m.diverged ? std::nullopt
                                     : std::optional<double>(m.sse / static_cast<double>(m.count)));
    }
    f.rows.push_back(std::move(row));
  }
  return f;
}

// Two campaigns of the same scenario with other seeds, unpaired: the runs of seeds 1..10 (BASE,
// 200 runs) against those of seeds 21..30 (NEW): every tested row of the flagship is shown within
// the default 5 %; with 3 runs a side (seed 1 against seed 21) nothing can be shown (exit 4).
void other_seeds_enough_and_too_few(const Scenario& sc, const std::vector<CampaignResult>& results,
                                    int seeds) {
  for (const std::size_t runs : {std::size_t{3}, std::size_t{200}}) {
    std::vector<CompareSample> rows;
    for (std::size_t e = 0; e < 6; ++e) {  // the open-loop row 6 diverges: never tested
      CompareSample s{sc.estimators[e].name, {}, {}, false};
      for (std::size_t k = 0; k < runs; ++k) {
        const auto& b = results[k / 20].runs[k % 20][e];
        const auto& n = results[static_cast<std::size_t>(seeds) + k / 20].runs[k % 20][e];
        s.base.push_back(b.sse / static_cast<double>(b.count));
        s.fresh.push_back(n.sse / static_cast<double>(n.count));
      }
      rows.push_back(std::move(s));
    }
    for (const auto& r : compare_samples(rows, CompareOptions{})) {
      std::printf("%zu runs a side, %s: %s %+.2f %% [%+.2f, %+.2f] at %.4g %%\n", runs,
                  r.estimator.c_str(), r.verdict.c_str(), 100 * *r.relative,
                  100 * r.relative_low.value_or(-1), 100 * r.relative_high.value_or(INFINITY),
                  100 * *r.ci_level);
      EXPECT_EQ(r.verdict, runs == 3 ? "inconclusive" : "unchanged") << r.estimator;
    }
  }
}

TEST(CompareStatistics, InjectedRegressionIsFlaggedAndAnUnchangedBuildIsNotOver20Seeds) {
  auto sc = flagship_with_variants();
  CampaignOptions opt;
  opt.time_estimators = false;
  opt.threads = 2;
  // 20 seeds; NCOSIM_COMPARE_SEEDS (at least 10) for a longer measurement outside the suite.
  const char* env_seeds = std::getenv("NCOSIM_COMPARE_SEEDS");
  const int seeds = env_seeds != nullptr && std::atoi(env_seeds) >= 10 ? std::atoi(env_seeds) : 20;
  std::vector<CampaignResult> results;
  std::vector<std::uint64_t> seed_of;
  // Seeds 1..20 with the extra rows; 21..40 (the unpaired null) with the 7 flagship rows only.
  auto plain = testing::load_one(source_path("scenarios/dolz2014_table2.toml"));
  for (int i = 0; i < 2 * seeds; ++i) {
    Scenario& s = i < seeds ? *sc : *plain;
    s.run.seed = static_cast<std::uint64_t>(1 + i);
    seed_of.push_back(s.run.seed);
    results.push_back(run_campaign(s, opt));
  }
  struct Injection {
    const char* row;
    const char* base_from;
    const char* new_from;
    int flagged = 0, others = 0;
    double relative = 0.0;
  };
  std::vector<Injection> inj{{"S1, 1 gain", "S1 ccl", "S1, 1 gain"},
                             {"S4, 60 gains", "S4, 60 gains", "S4 h2"},
                             {"S4, 60 gains", "S4, 60 gains", "S4 h3"}};
  // The width gain of pairing (Welch half-width / paired half-width) seed by seed: Kalman vs S4
  // (mse_ext and mse), and two close rows, S4 with history 4 vs 3 (mse). It depends on how
  // strongly the two rows' per-run errors are correlated.
  std::vector<double> gain_ext, gain_mse, gain_close;
  for (std::size_t i = 0; i < results.size(); ++i) {
    const auto& res = results[i];
    if (i < static_cast<std::size_t>(seeds)) {
      std::vector<double> h4_mse, h3_mse;
      for (const auto& run : res.runs) {
        h4_mse.push_back(run[4].sse / static_cast<double>(run[4].count));
        h3_mse.push_back(run[8].sse / static_cast<double>(run[8].count));
      }
      gain_close.push_back(*welch_difference(h4_mse, h3_mse)->diff_half /
                           *paired_difference(h4_mse, h3_mse)->diff_half);
    }
    for (const bool ext : {true, false}) {
      std::vector<double> kf, s4;
      for (const auto& run : res.runs) {
        kf.push_back((ext ? run[5].sse_ext : run[5].sse) / static_cast<double>(run[5].count));
        s4.push_back((ext ? run[4].sse_ext : run[4].sse) / static_cast<double>(run[4].count));
      }
      (ext ? gain_ext : gain_mse)
          .push_back(*welch_difference(kf, s4)->diff_half / *paired_difference(kf, s4)->diff_half);
    }
  }
  std::sort(gain_ext.begin(), gain_ext.end());
  std::sort(gain_mse.begin(), gain_mse.end());
  std::sort(gain_close.begin(), gain_close.end());
  ASSERT_EQ(sc->estimators[8].name, "S4 h3");
  std::printf(
      "S4 vs Kalman, Welch / paired half-width over %zu seeds: mse_ext min %.2f median %.2f max "
      "%.2f; "
      "mse min %.2f median %.2f max %.2f\n",
      gain_ext.size(), gain_ext.front(), gain_ext[gain_ext.size() / 2], gain_ext.back(),
      gain_mse.front(), gain_mse[gain_mse.size() / 2], gain_mse.back());
  std::printf("S4 history 3 vs 4, mse: min %.1f median %.1f max %.1f\n", gain_close.front(),
              gain_close[gain_close.size() / 2], gain_close.back());
  // Pairing must gain at every seed; on close rows at least the 5x the issue asks for.
  EXPECT_GT(gain_ext.front(), 1.0);
  EXPECT_GT(gain_mse.front(), 1.0);
  EXPECT_GE(gain_close.front(), 5.0);
  // Small regressions on the same seed: paired, at a 0.2 % tolerance (what ci-examples/ uses).
  CompareOptions o;
  o.tolerance = 0.002;
  int fp_same_seed = 0, md0_worse = 0, fp_other_seed = 0;
  double md0_low = INFINITY;
  for (int i = 0; i < seeds; ++i) {
    const auto& res = results[static_cast<std::size_t>(i)];
    const std::uint64_t seed = seed_of[static_cast<std::size_t>(i)];
    for (auto& in : inj) {
      const CompareResult r = compare_folders(folder(*sc, res, seed, in.row, in.base_from),
                                              folder(*sc, res, seed, in.row, in.new_from), o);
      for (const auto& row : r.rows) {
        if (row.estimator != in.row) {
          in.others += row.verdict == "worse" || row.verdict == "better";
          continue;
        }
        EXPECT_EQ(row.test, "paired");
        in.flagged += row.verdict == "worse";
        in.relative += *row.relative / seeds;
      }
    }
    const RunFolder base = folder(*sc, res, seed);
    // Unchanged build, same seed: identical runs.csv (paired, every ratio 1): unchanged, exit 0.
    fp_same_seed += compare_folders(base, base, o).exit_code();
    // Issue 40: NEW's Kalman row with max_delay = 0, at the default tolerance (5 %). It was
    // "unchanged" (a paired t-test, one run 36.6 against a median of 0.17), exit 0.
    const CompareResult k =
        compare_folders(base, folder(*sc, res, seed, "Kalman", "Kalman md0"), CompareOptions{});
    for (const auto& row : k.rows) {
      if (row.estimator != "Kalman") continue;
      md0_worse += row.verdict == "worse";
      md0_low = std::min(md0_low, *row.relative_low);
    }
    EXPECT_EQ(k.exit_code(), kCompareWorse);
    // Unchanged build, another seed: nothing to pair, unpaired on every row.
    const RunFolder other = folder(*sc, results[static_cast<std::size_t>(seeds + i)],
                                   seed_of[static_cast<std::size_t>(seeds + i)]);
    const CompareResult u = compare_folders(base, other, CompareOptions{});
    for (const auto& row : u.rows) {
      if (row.test != "none") {
        EXPECT_EQ(row.test, "unpaired");
      }
    }
    fp_other_seed += u.worse > 0;
  }
  // A false "worse" in a family of 6 Holm-corrected rows has probability <= 0.05 per seed: the
  // 99.9 % upper bound of Binomial(20, 0.05) bounds the unpaired false-positive count.
  const double bound = boost::math::quantile(
      boost::math::complement(boost::math::binomial_distribution<>(seeds, 0.05), 0.001));
  for (const auto& in : inj) {
    std::printf(
        "%s: %s -> %s, mean change %+.3f %%: flagged worse at %d/%d seeds; other rows flagged %d\n",
        in.row, in.base_from, in.new_from, 100.0 * in.relative, in.flagged, seeds, in.others);
    EXPECT_EQ(in.others, 0);
  }
  std::printf("Kalman max_delay 1 -> 0: worse at %d/%d seeds, smallest lower bound %+.0f %%\n",
              md0_worse, seeds, 100.0 * md0_low);
  std::printf(
      "unchanged build: gate failures same seed %d/%d, other seed (unpaired) worse %d/%d (bound "
      "%g)\n",
      fp_same_seed, seeds, fp_other_seed, seeds, bound);
  EXPECT_EQ(inj[0].flagged, seeds);  // +0.75 %
  EXPECT_EQ(inj[1].flagged, seeds);  // +1.9 %
  EXPECT_EQ(md0_worse, seeds);
  EXPECT_EQ(fp_same_seed, 0);
  EXPECT_LE(fp_other_seed, bound);
  other_seeds_enough_and_too_few(*sc, results, seeds);
}

}  // namespace
}  // namespace ncosim::sim
