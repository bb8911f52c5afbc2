// sim/analysis/paired.h — comparisons that use the common random numbers: every estimator of a case
// sees the same realisation in run r, and every sweep case the same streams (seed, r), so the
// per-run difference of two rows removes the run-to-run spread they share. Paired and Welch
// estimates of a difference and a ratio of means with confidence intervals, Holm's step-down
// correction, the [paired] scenario table and the paired columns of summary.csv.
// Failure behaviour: statistics return nullopt where they do not exist (fewer than 2 values,
// non-finite data); bad [paired] keys throw ScenarioError naming FILE:LINE and the key.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "config/config.h"
#include "sim/analysis/summary_row.h"

namespace ncosim::sim {

// ---- statistics ------------------------------------------------------------------------------

// Estimate of new - base and new / base with two-sided confidence intervals at `level`
// (half-widths), the degrees of freedom of the t law used and the test statistic of
// H0: mean(new) = (1 + margin) mean(base) (see relative_test).
struct Difference {
  double base_mean = 0.0, new_mean = 0.0;
  double diff = 0.0;                 // mean(new) - mean(base)
  std::optional<double> diff_half;   // CI half-width of diff
  std::optional<double> ratio;       // mean(new) / mean(base) (nullopt when mean(base) == 0)
  std::optional<double> ratio_half;  // delta-method CI half-width of the ratio
  double dof = 0.0;                  // degrees of freedom (paired: n - 1; Welch: Satterthwaite)
  std::size_t n_base = 0, n_new = 0;
  bool paired = false;
};

// Paired: a[i] and b[i] come from the same run. The CI of the mean difference uses the per-run
// differences d = b - a (Student t, n - 1 dof); the ratio's uses the linearised per-run values
// (b_i - R a_i) / mean(a) (delta method). Needs a.size() == b.size() >= 2.
std::optional<Difference> paired_difference(const std::vector<double>& base,
                                            const std::vector<double>& fresh, double level = 0.95);
// Unpaired (Welch): independent samples, Welch-Satterthwaite degrees of freedom. Needs >= 2 each.
std::optional<Difference> welch_difference(const std::vector<double>& base,
                                           const std::vector<double>& fresh, double level = 0.95);

// One-sided p-values against a relative margin m >= 0 (m = 0: plain difference):
//   worse:  H0 mean(new) <= (1 + m) mean(base)  vs  H1 mean(new) > (1 + m) mean(base)
//   better: H0 mean(new) >= (1 - m) mean(base)  vs  H1 mean(new) < (1 - m) mean(base)
// Paired: t-test on new_i - (1 ± m) base_i. Welch: on the means with the variance of
// new - (1 ± m) base. A zero standard error gives p = 0 or 1 by the sign of the estimate
// (exactly equal data: p = 1, never significant).
struct RelativeTest {
  double p_worse = 1.0, p_better = 1.0;
};
RelativeTest relative_test(const std::vector<double>& base, const std::vector<double>& fresh,
                           bool paired, double margin);

// Holm's step-down adjusted p-values (family-wise error <= alpha when rejecting adjusted <= alpha).
std::vector<double> holm_adjust(const std::vector<double>& p);

// Student-t quantile t_{1 - (1 - level)/2, dof}.
double t_two_sided(double dof, double level);

// ---- the [paired] table ----------------------------------------------------------------------

// The reference estimator of a case: [paired] reference, else the first estimator whose kind
// contains "kalman" (kalman_extended, kalman_buffer, sod_kalman), else the first estimator.
std::size_t reference_estimator_index(const Scenario& sc);

// The reference row of one case's summary rows (`rows`, in estimator order): [paired] reference
// whatever its status (the user chose it; paired_reference_note says why its columns are empty);
// else the first Kalman-type row whose status is ok, else the first row whose status is ok, else
// reference_estimator_index. A reference that diverged has no per-run values to pair with, so
// the default never picks one while an ok row exists.
std::size_t reference_row_index(const Scenario& sc, const std::vector<SummaryRow>& rows);

// One sentence per case whose reference row has no per-run mse (it diverged, or its design
// failed), so that the case's paired columns are empty: ' The reference "optimal N=1" has status
// diverged: no per-run mse to pair with, so its case's paired columns are empty.', then how to
// pick another; "" when every reference has its values.
std::string paired_reference_note(const std::vector<SummaryRow>& rows);

// The reference case (index into loaded.cases): [paired] reference_case, axes it does not name
// at their first value; the first case without it. Throws ScenarioError for a key that is not
// a sweep axis or a value that is not among the axis's values.
std::size_t reference_case_index(const LoadedScenario& loaded);

// ---- summary columns -------------------------------------------------------------------------

// Fills rows[i].paired for one case's rows (in estimator order) against rows[reference].
void add_paired_within(std::vector<SummaryRow>& case_rows, std::size_t reference);
// Fills the case_* columns of every row against the row of the same estimator in the reference
// case (rows grouped by case in case order, each case one row per estimator of its scenario).
// Runs are paired by index over the runs both cases have; a case whose seed differs from the
// reference case's is left empty (no common random numbers to pair).
void add_paired_across_cases(std::vector<SummaryRow>& rows, const LoadedScenario& loaded,
                             std::size_t reference_case);

// Column names appended to summary.csv (`sweeps`: whether the case columns are present) and
// one row's cells.
std::vector<std::string> paired_column_names(bool sweeps);
std::vector<std::string> paired_cells(const PairedColumns& p, bool sweeps);

}  // namespace ncosim::sim
