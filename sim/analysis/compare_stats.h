// sim/analysis/compare_stats.h — the statistics of `ncosim compare` (sim/analysis/compare.h): its
// options and a row's result, one row's test of the per-run ratio NEW / BASE, and the verdicts of
// a family of rows with Holm's correction and the intervals that read as their verdicts; and
// compare_samples(), the same judgement in process on per-run values (what `ncosim ladder` uses).
// docs/compare.md says what each step means and why.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "sim/analysis/rank_tests.h"

namespace ncosim::sim {

// The default --tolerance: a change of the typical per-run error within 5 % is "unchanged" when
// the runs show it (docs/compare.md, "The tolerance").
inline constexpr double kDefaultTolerance = 0.05;

struct CompareOptions {
  std::string metric = "mse";  // a per-run column of runs.csv: mse, mse_ext, mde_percent, rmse_xI
  double tolerance = kDefaultTolerance;  // relative, in [0, 1): the equivalence band 1 -+ T
  double alpha = 0.05;  // level of each one-sided test, in (0, 0.5); intervals at 1 - 2 alpha
  bool holm = true;     // Holm's correction over every tested row (each family of claims)
  bool allow_scenario_change = false;  // compare folders of another scenario text, --set or inputs
  bool allow_inconclusive = false;     // an inconclusive row passes the gate (exit 0, not 4)
};

// The exit codes of `ncosim compare` (README.md, "Exit codes").
inline constexpr int kCompareWorse = 1;         // a row is worse
inline constexpr int kCompareInconclusive = 4;  // no row worse, one inconclusive (and not allowed)

struct CompareRow {
  std::vector<std::string> labels;
  std::string estimator;
  // worse | better | unchanged | inconclusive | not comparable
  std::string verdict = "not comparable";
  std::string test = "none";  // paired (signed-rank) | unpaired (rank-sum) | none
  std::size_t runs_base = 0, runs_new = 0, pairs = 0;
  std::optional<double> base_mean, new_mean, diff;  // means of the runs tested, new - base
  // The typical per-run ratio NEW / BASE as its natural logarithm (Hodges–Lehmann) and the ends
  // of its interval at ci_level; +-inf where a run's value 0 decides it (a change from or to 0).
  std::optional<double> log_ratio, log_low, log_high;
  std::optional<double> relative, relative_low, relative_high;  // exp(log ...) - 1 where finite
  std::optional<double> ci_level;  // two-sided confidence of the interval: 1 - 2 a, a its level
  std::optional<double> p_worse, p_better, p_unchanged;  // one-sided; Holm-adjusted if on
  std::string note;
};

// ---- in process (e.g. `ncosim ladder`) -------------------------------------------------------

// One row's per-run values of the metric (finite, >= 0): BASE's and NEW's. Paired: run i of both
// drew the same random numbers (the same seed), base.size() == fresh.size().
struct CompareSample {
  std::string name;
  std::vector<double> base, fresh;
  bool paired = true;
};

// Judges every row as `ncosim compare` does (options.metric is only a label here; the
// allow_* options do not apply), the Holm correction over the rows given: result[i] is rows[i]'s.
// A row with fewer than 2 values on a side (paired: 2 pairs) is "not comparable". Throws
// std::invalid_argument for a value that is negative or not finite, or paired sizes that differ.
std::vector<CompareRow> compare_samples(const std::vector<CompareSample>& rows,
                                        const CompareOptions& options);

// What a tested row keeps until the family is judged: its shift values (logarithms of per-run
// ratios) and the largest |shift value| between non-zero values (beyond it a value 0 decides).
struct RowShift {
  ShiftValues shift;
  double finite_bound = 0.0;
};

// The test of one row on its values (finite, >= 0; paired: same sizes, run i of both from the
// same random numbers): fills out's test, pairs, means, diff and note; nullopt (out left "not
// comparable" with a note) when a side has fewer than 2 values.
std::optional<RowShift> test_values(const std::vector<double>& base,
                                    const std::vector<double>& fresh, bool paired, CompareRow& out);

// The verdicts of rows[i] for which shifts[i] is set (the tested rows, one family): p-values
// (Holm-adjusted when options.holm), verdict, the interval at the level that decided the row and
// its ci_level; a note where the ratio of the means lies outside that interval.
void judge_family(std::vector<CompareRow>& rows, const std::vector<std::optional<RowShift>>& shifts,
                  const CompareOptions& options);

// A ratio given by its natural logarithm, readable at any size: "×1.01", "×116", "×0.0123",
// "×1.2e+160" (computed from the logarithm: no overflow), "×inf", "×0".
std::string ratio_text(double log_ratio);

}  // namespace ncosim::sim
