// sim/run/trend.h — does a quantity grow through a run? A one-sided trend test on block means of
// each run of a campaign (a link's packet delays, an estimator's log error), for the overload
// test of links.csv and the error-growth note (sim/run/overload.h; results/README.md, "Overload
// and growth").
//
// The block means of a bursty link (Gilbert–Elliott, Markov) are autocorrelated: a test that takes
// them for independent points (ordinary least squares, or Mann–Kendall with its textbook variance)
// sees a trend in every long burst and false-alarms far above its level. Two tests that do not:
//  - kMinRunsAcross runs or more (the usual case): the runs of a campaign are independent
//    replications, so each run's least-squares slope of its block means is one independent draw;
//    under a stationary link E[slope] = 0 exactly (the slope is linear in block means that all
//    have one mean, whatever their correlation), and Student's t over the runs' slopes tests it
//    with the spread between runs, which holds every within-run correlation: no model of it.
//  - fewer runs (Student t with 1 to 3 degrees of freedom cannot see even a queue that grows by
//    hundreds of periods): Mann–Kendall on kBatches batch means of each run, each an eighth of
//    its blocks, the runs' S summed, with the sum's exact null law (every order of each run's
//    batch means equally likely, runs independent). It assumes the link forgets its state within
//    an eighth of a run (its batch means then nearly independent); where it does not, the test is
//    liberal (measured in results/README.md, "Overload and growth").
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

namespace ncosim::sim {

// One run's block means: y[i] at t[i] in [0, 1], the block's centre as a share of the run.
struct BlockSeries {
  std::vector<double> t, y;
};

// The least-squares line y = a + b t: a at the run's start, b the change over the whole run.
// nullopt with fewer than 3 points or all t equal.
struct Line {
  double a = 0.0, b = 0.0;
};
std::optional<Line> fit_line(const BlockSeries& s);

inline constexpr std::size_t kMinRunsAcross = 5;
inline constexpr std::size_t kBatches = 8;

struct TrendResult {
  double first = 0.0, last = 0.0;  // the runs' first and last block means, mean over the runs
  double growth = 0.0;   // the least-squares line's change over the run (its slope), mean over runs
  double p = 1.0;        // one-sided p-value of "grows" (slope > 0)
  std::size_t runs = 0;  // runs with at least min_blocks points (the test's sample)
  bool across_runs = true;  // Student t over the runs' slopes; false: Mann–Kendall (< 5 runs)
};

// The test over the runs with at least `min_blocks` points (>= 3); nullopt when none has.
// min_blocks >= 2 kBatches keeps every batch of at least two blocks.
std::optional<TrendResult> trend_test(const std::vector<BlockSeries>& runs, std::size_t min_blocks);

// One-sided p of Student t over per-run slopes (mean > 0); 0 or 1 when they are all equal.
double slopes_p(const std::vector<double>& slopes);

// One-sided p of Mann–Kendall's S > 0 summed over independent series (each in order):
// P(sum S >= s) under the null that every order of each series is equally likely, exact without
// ties (series of up to 20 points, up to 2000 pairs in all), else the normal approximation with the
// ties' variance; 1 when the sum is <= 0.
double mann_kendall_p(const std::vector<std::vector<double>>& series);

// The means of y cut into k consecutive batches of (nearly) equal count; y itself when shorter.
std::vector<double> batch_means(const std::vector<double>& y, std::size_t k);

}  // namespace ncosim::sim
