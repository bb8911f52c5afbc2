// sim/analysis/rank_tests.h — distribution-free inference on a shift: the Wilcoxon signed-rank test
// (paired values) and the Wilcoxon–Mann–Whitney rank-sum test (two independent samples), each with
// its Hodges–Lehmann estimate and the confidence interval obtained by inverting the test. What
// `ncosim compare` judges a row with (sim/analysis/compare.h, docs/compare.md).
//
// A shift is inferred from a set of N "shift values" w: paired, the Walsh averages
// (d_i + d_j) / 2, i <= j, of the differences d (N = n (n + 1) / 2); unpaired, the differences
// y_j - x_i (N = m n). Under H0 "the shift is delta" (d symmetric about delta; y - delta
// distributed as x) the count #{w > delta} follows the signed-rank (resp. Mann–Whitney) null law,
// whatever the distribution of the data (continuous): the test stays exact under heavy tails.
// The estimate is the median of w; the one-sided bounds at level a are order statistics of w, so
// that "the bound excludes delta" and "the one-sided p-value against delta is <= a" are the same
// statement, in floating point too (one count, one table). A value w equal to delta counts against
// the claim (conservative for ties).
//
// The null laws are exact (a dynamic program, each size computed once per process) up to n = 200
// (signed-rank) or min(m, n)^2 (m + n)^2 <= 1e7 (rank-sum: up to 39 runs a side), and the normal
// approximation with a continuity correction beyond. The w are
// never stored: order statistics are found by bisection over the doubles, counting in O(n).
// Failure behaviour: empty samples are programmer errors (checked by the callers); non-finite
// values are not allowed (the caller maps them to finite ones).
#pragma once

#include <cstddef>
#include <limits>
#include <memory>
#include <vector>

namespace ncosim::sim {

// The null law of a count S in 0 .. N (N = max()): P0(S >= c).
class RankNull {
 public:
  // W+ of n paired values (N = n (n + 1) / 2).
  static RankNull signed_rank(std::size_t n);
  // U of samples of sizes m and n (N = m n).
  static RankNull rank_sum(std::size_t m, std::size_t n);

  std::size_t max() const { return n_; }
  bool exact() const { return tail_ != nullptr; }
  // P0(S >= c); 1 for c == 0, 0 for c > max().
  double upper_tail(std::size_t c) const;
  // The smallest c with P0(S >= c) <= a (max() + 1 when there is none: too few values).
  std::size_t critical(double a) const;

 private:
  std::size_t n_ = 0;
  double mean_ = 0.0, sd_ = 0.0;  // of the normal approximation
  // Exact: (*tail_)[c] = P0(S >= c), c = 0 .. N + 1; shared by every law of the same sizes (a
  // compare of many rows computes each table once).
  std::shared_ptr<const std::vector<double>> tail_;
};

// The shift values of a sample and counts over them.
class ShiftValues {
 public:
  // Paired: the Walsh averages of d (one value per run: log(new / base)).
  static ShiftValues walsh(std::vector<double> d);
  // Unpaired: y_j - x_i (x: BASE's values, y: NEW's).
  static ShiftValues differences(std::vector<double> x, std::vector<double> y);

  std::size_t count() const;          // N
  std::size_t above(double t) const;  // #{w > t}
  std::size_t below(double t) const;  // #{w < t}
  double kth(std::size_t k) const;    // the k-th smallest w, 1 <= k <= N
  double median() const;              // the Hodges–Lehmann estimate
  const RankNull& null_law() const { return null_; }

  // The lower / upper bound of the one-sided (1 - a) confidence interval: the c-th largest /
  // smallest w with c = null_law().critical(a); -inf / +inf when c > N.
  double lower(double a) const;
  double upper(double a) const;
  // One-sided p-values: of H0 shift <= t (small when w lie above t) and of H0 shift >= t.
  double p_above(double t) const { return null_.upper_tail(above(t)); }
  double p_below(double t) const { return null_.upper_tail(below(t)); }

 private:
  ShiftValues(bool paired, std::vector<double> x, std::vector<double> y, RankNull null);
  std::size_t at_most(double t) const;  // #{w <= t}
  bool paired_ = true;
  std::vector<double> x_, y_;  // sorted; paired: x_ = d, y_ unused
  RankNull null_;
};

}  // namespace ncosim::sim
