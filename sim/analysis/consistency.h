// sim/analysis/consistency.h — filter consistency: is an estimator's own covariance honest about
// its error? The normalised estimation error squared, NEES = e' P^-1 e (e = x - xhat, P the
// filter's covariance of x), and the normalised innovation squared, NIS = nu' S^-1 nu, are
// chi-square with n (state size) and m (rows of the update) degrees of freedom when the filter is
// consistent (Bar-Shalom, Li & Kirubarajan 2001, section 5.4). The campaign's averages are compared
// with the two-sided 95 % chi-square bounds; results/README.md, "nees and nis", gives the
// definitions.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace ncosim::sim {

// An average with the two-sided 95 % bounds a consistent filter's average stays within.
struct ConsistencyStat {
  double mean = 0.0;
  double lo = 0.0, hi = 0.0;
  bool inside() const { return mean >= lo && mean <= hi; }
};

// Sums over a campaign's runs (EstimatorRunMetrics' nees/nis fields) of one estimator.
struct ConsistencySums {
  double nees = 0.0;
  std::int64_t nees_count = 0;  // periods scored, over every run
  std::int64_t nees_runs = 0;   // runs with at least one period scored
  double nis = 0.0;
  std::int64_t nis_dof = 0, nis_count = 0;
};

// The average NEES per period, with the bounds of chi2(runs x n) / runs: the bounds of the
// run-average at one period (errors of different runs are independent). The time average over
// the periods has at most that average's variance (the per-period averages are correlated in
// time, so no narrower bound holds without a model of that correlation): a filter outside them
// is inconsistent, one inside may still be mildly so. nullopt when no period was scored.
std::optional<ConsistencyStat> nees_stat(const ConsistencySums& s, std::int64_t n);
// The average NIS per update, with the bounds of chi2(sum of rows) / updates: a consistent
// filter's innovations are white, so the sum over every update is chi-square with the summed
// degrees of freedom. nullopt when no update was counted.
std::optional<ConsistencyStat> nis_stat(const ConsistencySums& s);
// "NIS 1.669 below [1.670, 1.683]": the average, where it lies ("in", "below" or "above", as
// inside() and consistency_note judge) and the bounds, all three with the same significant
// digits (trailing zeros kept): 4, or as many more (up to 17) as it takes for the printed
// numbers to order as the values do, so that a value just outside never prints equal to its
// bound.
std::string consistency_stat_text(const std::string& name, const ConsistencyStat& s);
// The summary's `consistency` cell: empty without a statistic, "ok" when both are inside their
// bounds, else what is outside and what it means (e.g. "NEES above its 95 % bound: the
// covariance is too small (overconfident)").
std::string consistency_note(const std::optional<ConsistencyStat>& nees,
                             const std::optional<ConsistencyStat>& nis);

}  // namespace ncosim::sim
