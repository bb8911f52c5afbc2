// sim/analysis/rank_tests.cc — signed-rank and rank-sum null laws, Hodges–Lehmann estimates and
// intervals by counting (sim/analysis/rank_tests.h).
#include "sim/analysis/rank_tests.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <map>
#include <mutex>
#include <tuple>

#include "kernel/check.h"

namespace ncosim::sim {

namespace {

// Largest n for the exact signed-rank law (n^3 / 4 operations: 2e6 at 200).
constexpr std::size_t kExactSignedRank = 200;
// Largest k^2 N^2 (k = min(m, n), N = m + n) for the exact rank-sum law (its operations).
constexpr double kExactRankSumWork = 1e7;

// P(Z >= z) for a standard normal Z.
double normal_upper(double z) { return 0.5 * std::erfc(z / std::sqrt(2.0)); }

// tail[c] = P(S >= c), c = 0 .. N + 1, from the point probabilities p[0 .. N] (summed from the
// top: the upper tail keeps its relative accuracy).
std::vector<double> upper_tails(const std::vector<double>& p) {
  std::vector<double> tail(p.size() + 1, 0.0);
  for (std::size_t c = p.size(); c-- > 0;) tail[c] = tail[c + 1] + p[c];
  for (double& t : tail) t = std::min(t, 1.0);
  tail[0] = 1.0;
  return tail;
}

// A double's position in the order of the doubles, as an unsigned integer (monotone: a < b iff
// key(a) < key(b), for non-NaN values; -0 and +0 are adjacent).
std::uint64_t order_key(double x) {
  const auto u = std::bit_cast<std::uint64_t>(x);
  return (u >> 63) != 0 ? ~u : (u | 0x8000000000000000ULL);
}

double from_order_key(std::uint64_t k) {
  return std::bit_cast<double>((k >> 63) != 0 ? (k & 0x7FFFFFFFFFFFFFFFULL) : ~k);
}

// The exact tail tables computed so far, by (law, m, n): each computed once per process.
using TailTable = std::shared_ptr<const std::vector<double>>;
TailTable cached(char law, std::size_t m, std::size_t n,
                 std::vector<double> (*compute)(std::size_t, std::size_t)) {
  static std::mutex mutex;
  static std::map<std::tuple<char, std::size_t, std::size_t>, TailTable> tables;
  const std::lock_guard<std::mutex> lock(mutex);
  auto& t = tables[{law, m, n}];
  if (!t) t = std::make_shared<const std::vector<double>>(compute(m, n));
  return t;
}

// P(W+ >= c) of n ranks: the probability that the ranks with a positive sign sum to s, each sign
// 1/2, summed from the top.
std::vector<double> signed_rank_tail(std::size_t n, std::size_t /*unused*/) {
  std::vector<double> p(n * (n + 1) / 2 + 1, 0.0);
  p[0] = 1.0;
  std::size_t top = 0;
  for (std::size_t k = 1; k <= n; ++k) {
    top += k;
    for (std::size_t s = top + 1; s-- > 0;) p[s] = 0.5 * (p[s] + (s >= k ? p[s - k] : 0.0));
  }
  return upper_tails(p);
}

// P(U >= c) of samples of m and n: ways[j][s] counts the subsets of j of the first e elements
// (0-based ranks) whose ranks sum to s; U is the sum of the k = min(m, n) chosen ranks minus
// k (k - 1) / 2 (each pair counted once), in 0 .. m n.
std::vector<double> rank_sum_tail(std::size_t m, std::size_t n) {
  const std::size_t k = std::min(m, n), total = m + n, width = k * total + 1;
  std::vector<std::vector<double>> ways(k + 1, std::vector<double>(width, 0.0));
  ways[0][0] = 1.0;
  for (std::size_t e = 0; e < total; ++e) {
    for (std::size_t j = std::min(e + 1, k); j >= 1; --j) {
      for (std::size_t s = width; s-- > e;) ways[j][s] += ways[j - 1][s - e];
    }
  }
  const std::size_t offset = k * (k - 1) / 2;
  std::vector<double> p(m * n + 1, 0.0);
  double all = 0.0;
  for (std::size_t u = 0; u <= m * n; ++u) all += ways[k][u + offset];
  for (std::size_t u = 0; u <= m * n; ++u) p[u] = ways[k][u + offset] / all;
  return upper_tails(p);
}

}  // namespace

RankNull RankNull::signed_rank(std::size_t n) {
  RankNull r;
  r.n_ = n * (n + 1) / 2;
  const double nd = static_cast<double>(n);
  r.mean_ = nd * (nd + 1.0) / 4.0;
  r.sd_ = std::sqrt(nd * (nd + 1.0) * (2.0 * nd + 1.0) / 24.0);
  if (n <= kExactSignedRank) r.tail_ = cached('s', n, 0, signed_rank_tail);
  return r;
}

RankNull RankNull::rank_sum(std::size_t m, std::size_t n) {
  RankNull r;
  r.n_ = m * n;
  const double md = static_cast<double>(m), nd = static_cast<double>(n);
  r.mean_ = md * nd / 2.0;
  r.sd_ = std::sqrt(md * nd * (md + nd + 1.0) / 12.0);
  const std::size_t k = std::min(m, n), total = m + n;
  const double kd = static_cast<double>(k), td = static_cast<double>(total);
  if (kd * kd * td * td <= kExactRankSumWork) r.tail_ = cached('r', m, n, rank_sum_tail);
  return r;
}

double RankNull::upper_tail(std::size_t c) const {
  if (c == 0) return 1.0;
  if (c > n_) return 0.0;
  if (exact()) return (*tail_)[c];
  if (!(sd_ > 0.0)) return 0.0;
  return normal_upper((static_cast<double>(c) - 0.5 - mean_) / sd_);
}

std::size_t RankNull::critical(double a) const {
  // upper_tail is non-increasing in c: the first c with tail <= a by bisection on [0, N + 1].
  std::size_t lo = 0, hi = n_ + 1;  // upper_tail(hi) = 0 <= a; the answer is in (lo, hi]
  while (hi - lo > 1) {
    const std::size_t mid = lo + (hi - lo) / 2;
    if (upper_tail(mid) <= a) {
      hi = mid;
    } else {
      lo = mid;
    }
  }
  return upper_tail(lo) <= a ? lo : hi;
}

ShiftValues::ShiftValues(bool paired, std::vector<double> x, std::vector<double> y, RankNull null)
    : paired_(paired), x_(std::move(x)), y_(std::move(y)), null_(std::move(null)) {
  std::sort(x_.begin(), x_.end());
  std::sort(y_.begin(), y_.end());
}

ShiftValues ShiftValues::walsh(std::vector<double> d) {
  NCOSIM_CHECK(!d.empty());
  const std::size_t n = d.size();
  return ShiftValues(true, std::move(d), {}, RankNull::signed_rank(n));
}

ShiftValues ShiftValues::differences(std::vector<double> x, std::vector<double> y) {
  NCOSIM_CHECK(!x.empty() && !y.empty());
  const std::size_t m = x.size(), n = y.size();
  return ShiftValues(false, std::move(x), std::move(y), RankNull::rank_sum(m, n));
}

std::size_t ShiftValues::count() const { return null_.max(); }

std::size_t ShiftValues::at_most(double t) const {
  std::size_t c = 0;
  if (paired_) {
    // Pairs i <= j with (d_i + d_j) / 2 <= t: for each i, j runs up to the largest index that
    // qualifies, which does not grow with i (rounding is monotone).
    const std::size_t n = x_.size();
    std::size_t j = n;  // one past the largest qualifying index
    for (std::size_t i = 0; i < n; ++i) {
      while (j > i && (x_[i] + x_[j - 1]) * 0.5 > t) --j;
      if (j <= i) break;
      c += j - i;
    }
    return c;
  }
  // Pairs with y_j - x_i <= t: for each j, the x_i from a first index on (which does not fall as
  // y_j grows).
  std::size_t i = 0;
  for (const double yj : y_) {
    while (i < x_.size() && yj - x_[i] > t) ++i;
    c += x_.size() - i;
  }
  return c;
}

std::size_t ShiftValues::above(double t) const { return count() - at_most(t); }

std::size_t ShiftValues::below(double t) const {
  return at_most(std::nextafter(t, -std::numeric_limits<double>::infinity()));
}

double ShiftValues::kth(std::size_t k) const {
  NCOSIM_CHECK(k >= 1 && k <= count());
  const double lo = paired_ ? x_.front() : y_.front() - x_.back();
  const double hi = paired_ ? x_.back() : y_.back() - x_.front();
  // The smallest double t with #{w <= t} >= k is the k-th smallest w.
  std::uint64_t a = order_key(lo), b = order_key(hi);  // at_most(hi) = N >= k
  if (at_most(lo) >= k) return lo + 0.0;
  while (b - a > 1) {
    const std::uint64_t mid = a + (b - a) / 2;
    if (at_most(from_order_key(mid)) >= k) {
      b = mid;
    } else {
      a = mid;
    }
  }
  return from_order_key(b) + 0.0;
}

double ShiftValues::median() const {
  const std::size_t n = count();
  if (n % 2 == 1) return kth((n + 1) / 2);
  const double a = kth(n / 2), b = kth(n / 2 + 1);
  return a + (b - a) / 2.0;
}

double ShiftValues::lower(double a) const {
  const std::size_t c = null_.critical(a);
  return c > count() ? -std::numeric_limits<double>::infinity() : kth(count() - c + 1);
}

double ShiftValues::upper(double a) const {
  const std::size_t c = null_.critical(a);
  return c > count() ? std::numeric_limits<double>::infinity() : kth(c);
}

}  // namespace ncosim::sim
