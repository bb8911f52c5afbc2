// sim/run/trend.cc — the trend tests of sim/run/trend.h.
#include "sim/run/trend.h"

#include <algorithm>
#include <boost/math/distributions/normal.hpp>
#include <boost/math/distributions/students_t.hpp>
#include <cmath>
#include <cstdint>
#include <numeric>

namespace ncosim::sim {

std::optional<Line> fit_line(const BlockSeries& s) {
  const std::size_t n = std::min(s.t.size(), s.y.size());
  if (n < 3) return std::nullopt;
  double tm = 0.0, ym = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    tm += s.t[i];
    ym += s.y[i];
  }
  tm /= static_cast<double>(n);
  ym /= static_cast<double>(n);
  double stt = 0.0, sty = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    stt += (s.t[i] - tm) * (s.t[i] - tm);
    sty += (s.t[i] - tm) * (s.y[i] - ym);
  }
  if (!(stt > 0.0)) return std::nullopt;
  Line l;
  l.b = sty / stt;
  l.a = ym - l.b * tm;
  return l;
}

double slopes_p(const std::vector<double>& slopes) {
  const auto r = static_cast<double>(slopes.size());
  if (slopes.size() < 2) return 1.0;
  const double mean = std::accumulate(slopes.begin(), slopes.end(), 0.0) / r;
  double ss = 0.0;
  for (const double b : slopes) ss += (b - mean) * (b - mean);
  const double sd = std::sqrt(ss / (r - 1.0));
  if (!(sd > 1e-12 * std::max(1.0, std::abs(mean)))) return mean > 0.0 ? 0.0 : 1.0;
  const boost::math::students_t t(r - 1.0);
  return boost::math::cdf(boost::math::complement(t, mean / (sd / std::sqrt(r))));
}

namespace {

// Kendall's S of one series (in order), its null variance with the ties' correction, and n.
struct KendallS {
  std::int64_t s = 0;
  double var = 0.0;
  bool ties = false;
  std::size_t n = 0;
};
KendallS kendall_s(const std::vector<double>& y) {
  KendallS k;
  k.n = y.size();
  for (std::size_t i = 0; i < k.n; ++i) {
    for (std::size_t j = i + 1; j < k.n; ++j) {
      k.s += (y[j] > y[i]) - (y[j] < y[i]);
      k.ties = k.ties || y[j] == y[i];
    }
  }
  // Var(S) = (n(n-1)(2n+5) - sum over groups of t tied values of t(t-1)(2t+5)) / 18.
  std::vector<double> sorted = y;
  std::sort(sorted.begin(), sorted.end());
  const auto nd = static_cast<double>(k.n);
  k.var = nd * (nd - 1.0) * (2.0 * nd + 5.0);
  for (std::size_t i = 0; i < k.n;) {
    std::size_t j = i;
    while (j + 1 < k.n && sorted[j + 1] == sorted[i]) ++j;
    const auto t = static_cast<double>(j - i + 1);
    k.var -= t * (t - 1.0) * (2.0 * t + 5.0);
    i = j + 1;
  }
  k.var /= 18.0;
  return k;
}

// The Mahonian numbers of n: how many orders of n distinct values have k inversions, k = 0 ..
// n (n-1) / 2, as shares of n!.
std::vector<double> inversion_law(std::size_t n) {
  const std::size_t pairs = n * (n - 1) / 2;
  std::vector<double> law(pairs + 1, 0.0);
  law[0] = 1.0;
  for (std::size_t m = 2; m <= n; ++m) {  // an order of m: one of m - 1, the new value in m places
    std::vector<double> next(pairs + 1, 0.0);
    for (std::size_t k = 0; k <= pairs; ++k) {
      if (law[k] == 0.0) continue;
      for (std::size_t add = 0; add < m && k + add <= pairs; ++add)
        next[k + add] += law[k] / static_cast<double>(m);
    }
    law = std::move(next);
  }
  return law;
}

}  // namespace

std::vector<double> batch_means(const std::vector<double>& y, std::size_t k) {
  std::vector<double> out;
  if (y.size() < k) return y;
  for (std::size_t b = 0; b < k; ++b) {
    const std::size_t lo = b * y.size() / k, hi = (b + 1) * y.size() / k;
    double sum = 0.0;
    for (std::size_t i = lo; i < hi; ++i) sum += y[i];
    out.push_back(sum / static_cast<double>(hi - lo));
  }
  return out;
}

double mann_kendall_p(const std::vector<std::vector<double>>& series) {
  std::int64_t s = 0;
  double var = 0.0;
  bool exact = true;
  std::size_t pairs = 0;
  std::vector<double> law{1.0};  // the law of the inversions summed over the series
  for (const auto& y : series) {
    const KendallS k = kendall_s(y);
    s += k.s;
    var += k.var;
    pairs += k.n * (k.n - 1) / 2;
    exact = exact && !k.ties && k.n <= 20 && pairs <= 2000;
    if (!exact) continue;
    const std::vector<double> one = inversion_law(k.n);
    std::vector<double> sum(law.size() + one.size() - 1, 0.0);
    for (std::size_t a = 0; a < law.size(); ++a)
      for (std::size_t b = 0; b < one.size(); ++b) sum[a + b] += law[a] * one[b];
    law = std::move(sum);
  }
  if (s <= 0 || !(var > 0.0)) return s > 0 ? 0.0 : 1.0;
  if (!exact) {  // the normal approximation, with a continuity correction
    const double z = (static_cast<double>(s) - 1.0) / std::sqrt(var);
    return boost::math::cdf(boost::math::complement(boost::math::normal(), z));
  }
  // Without ties S = N - 2 inv (N: the pairs), so P(S >= s) = P(inv <= (N - s) / 2).
  const auto most = static_cast<std::size_t>((static_cast<std::int64_t>(pairs) - s) / 2);
  double p = 0.0;
  for (std::size_t k = 0; k <= most && k < law.size(); ++k) p += law[k];
  return std::min(1.0, p);
}

std::optional<TrendResult> trend_test(const std::vector<BlockSeries>& runs,
                                      std::size_t min_blocks) {
  std::vector<double> slopes;
  TrendResult out;
  std::vector<std::vector<double>> batches;
  for (const BlockSeries& s : runs) {
    if (s.y.size() < std::max<std::size_t>(min_blocks, 3)) continue;
    const std::optional<Line> l = fit_line(s);
    if (!l) continue;
    slopes.push_back(l->b);
    out.growth += l->b;
    out.first += s.y.front();
    out.last += s.y.back();
    batches.push_back(batch_means(s.y, kBatches));
  }
  if (slopes.empty()) return std::nullopt;
  out.runs = slopes.size();
  out.growth /= static_cast<double>(out.runs);
  out.first /= static_cast<double>(out.runs);
  out.last /= static_cast<double>(out.runs);
  out.across_runs = out.runs >= kMinRunsAcross;
  out.p = out.across_runs ? slopes_p(slopes) : mann_kendall_p(batches);
  return out;
}

}  // namespace ncosim::sim
