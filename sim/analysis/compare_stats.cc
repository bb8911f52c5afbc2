// sim/analysis/compare_stats.cc — one row's rank test of the per-run ratio and the verdicts of a
// family of rows (sim/analysis/compare_stats.h).
#include "sim/analysis/compare_stats.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

#include "sim/analysis/paired.h"

namespace ncosim::sim {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

void add_note(CompareRow& out, const std::string& text) {
  out.note += (out.note.empty() ? "" : "; ") + text;
}

// The mean of values >= 0 without overflow (each term divided first).
double mean_of(const std::vector<double>& v) {
  double m = 0.0;
  for (double x : v) m += x / static_cast<double>(v.size());
  return m;
}

// Holm's step-down over one family: per row, whether its claim is made and the one-sided level of
// the step that decided it (made: the step's alpha / k; not made: the level of the first step that
// failed, at which no later row's p-value passes either). Without the correction: alpha each.
struct Levels {
  std::vector<bool> made;
  std::vector<double> level;
};
Levels holm_levels(const std::vector<double>& p, double alpha, bool holm) {
  const std::size_t m = p.size();
  Levels out{std::vector<bool>(m, false), std::vector<double>(m, alpha)};
  if (!holm) {
    for (std::size_t i = 0; i < m; ++i) out.made[i] = p[i] <= alpha;
    return out;
  }
  std::vector<std::size_t> order(m);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return p[a] < p[b]; });
  bool stepping = true;
  double failed = alpha;
  for (std::size_t j = 0; j < m; ++j) {
    const std::size_t k = order[j];
    const double step = alpha / static_cast<double>(m - j);
    if (stepping && p[k] <= step) {
      out.made[k] = true;
      // Rows of equal p-values share the first one's level (it holds for them too): equal rows,
      // equal intervals.
      const bool tie = j > 0 && p[order[j - 1]] == p[k];
      out.level[k] = tie ? out.level[order[j - 1]] : step;
      continue;
    }
    if (stepping) failed = step;
    stepping = false;
    out.level[k] = failed;
  }
  return out;
}

// A shift value as the log of a ratio: beyond the bound of non-zero values, a value 0 decided it
// (a ratio of 0 or infinity).
double as_log_ratio(double w, double finite_bound) {
  if (w > finite_bound) return kInf;
  if (w < -finite_bound) return -kInf;
  return w;
}

std::optional<double> relative_of(double log_ratio) {
  const double r = std::expm1(log_ratio);
  return std::isfinite(r) ? std::optional<double>(r) : std::nullopt;
}

// One tested row's verdict, interval at `level` and the note on its means.
void set_verdict(CompareRow& row, const RowShift& s, const std::string& verdict, double level) {
  row.verdict = verdict;
  row.ci_level = 1.0 - 2.0 * level;
  row.log_ratio = as_log_ratio(s.shift.median(), s.finite_bound);
  row.log_low = as_log_ratio(s.shift.lower(level), s.finite_bound);
  row.log_high = as_log_ratio(s.shift.upper(level), s.finite_bound);
  row.relative = relative_of(*row.log_ratio);
  row.relative_low = relative_of(*row.log_low);
  row.relative_high = relative_of(*row.log_high);
  if (!row.relative || !row.relative_low || !row.relative_high) {
    add_note(row,
             "a ratio beyond the range of a double (a change from 0, or too few runs for a "
             "bound): its relative cell is empty");
  }
  // The typical ratio and the ratio of the means part when a few runs weigh on the means.
  if (row.base_mean && row.new_mean && *row.base_mean > 0.0 && std::isfinite(*row.log_low) &&
      std::isfinite(*row.log_high)) {
    const double means = std::log(*row.new_mean) - std::log(*row.base_mean);
    if (means < *row.log_low || means > *row.log_high) {
      add_note(row, fmt::format("the ratio of the means, {}, lies outside the interval: a few runs "
                                "weigh on the means (the verdict judges the typical run)",
                                ratio_text(means)));
    }
  }
}

}  // namespace

std::string ratio_text(double log_ratio) {
  if (std::isnan(log_ratio)) return "–";
  if (log_ratio == kInf) return "×inf";
  if (log_ratio == -kInf) return "×0";
  const double e10 = log_ratio / std::log(10.0);
  if (std::abs(e10) < 4.0) return fmt::format("×{:.3g}", std::exp(log_ratio));
  int exponent = static_cast<int>(std::floor(e10));
  double mantissa = std::pow(10.0, e10 - exponent);
  if (mantissa >= 9.995) {  // would print as 10.0
    mantissa /= 10.0;
    ++exponent;
  }
  return fmt::format("×{:.3g}e{:+d}", mantissa, exponent);
}

std::optional<RowShift> test_values(const std::vector<double>& base,
                                    const std::vector<double>& fresh, bool paired,
                                    CompareRow& out) {
  if (base.size() < 2 || fresh.size() < 2) {
    add_note(out, paired ? "fewer than 2 pairs" : "fewer than 2 runs");
    return std::nullopt;
  }
  out.test = paired ? "paired" : "unpaired";
  out.pairs = paired ? base.size() : 0;
  out.base_mean = mean_of(base);
  out.new_mean = mean_of(fresh);
  out.diff = *out.new_mean - *out.base_mean;
  // Logarithms; a value 0 gets one below every other by more than any ratio of non-zero values,
  // so that a change from or to 0 ranks beyond every other (and 0 -> 0 is no change).
  double lo = kInf, hi = -kInf;
  std::size_t zeros = 0;
  for (const auto* v : {&base, &fresh}) {
    for (double x : *v) {
      if (x > 0.0) {
        lo = std::min(lo, std::log(x));
        hi = std::max(hi, std::log(x));
      } else {
        ++zeros;
      }
    }
  }
  if (lo > hi) lo = hi = 0.0;
  const double span = hi - lo, zero_log = lo - 1000.0 * (span + 1.0);
  const auto log_of = [&](double x) { return x > 0.0 ? std::log(x) : zero_log; };
  if (zeros > 0) {
    add_note(out, fmt::format("{} value(s) 0: a change from or to 0 counts as larger than any "
                              "other",
                              zeros));
  }
  if (paired) {
    std::vector<double> d(base.size());
    for (std::size_t i = 0; i < d.size(); ++i) d[i] = log_of(fresh[i]) - log_of(base[i]);
    return RowShift{ShiftValues::walsh(std::move(d)), span};
  }
  std::vector<double> x(base.size()), y(fresh.size());
  std::transform(base.begin(), base.end(), x.begin(), log_of);
  std::transform(fresh.begin(), fresh.end(), y.begin(), log_of);
  return RowShift{ShiftValues::differences(std::move(x), std::move(y)), span};
}

void judge_family(std::vector<CompareRow>& rows, const std::vector<std::optional<RowShift>>& shifts,
                  const CompareOptions& o) {
  std::vector<std::size_t> tested;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (shifts[i]) tested.push_back(i);
  }
  // The margins in the log of the ratio: worse above log(1 + T), better below log(1 - T).
  const double up = std::log1p(o.tolerance), down = std::log1p(-o.tolerance);
  std::vector<double> pw, pb, pe;
  for (const std::size_t i : tested) {
    const ShiftValues& s = shifts[i]->shift;
    pw.push_back(s.p_above(up));
    pb.push_back(s.p_below(down));
    pe.push_back(std::max(s.p_above(down), s.p_below(up)));  // TOST: both one-sided tests
  }
  const Levels lw = holm_levels(pw, o.alpha, o.holm), lb = holm_levels(pb, o.alpha, o.holm),
               le = holm_levels(pe, o.alpha, o.holm);
  const std::vector<double> aw = o.holm ? holm_adjust(pw) : pw;
  const std::vector<double> ab = o.holm ? holm_adjust(pb) : pb;
  const std::vector<double> ae = o.holm ? holm_adjust(pe) : pe;
  for (std::size_t j = 0; j < tested.size(); ++j) {
    CompareRow& row = rows[tested[j]];
    row.p_worse = aw[j];
    row.p_better = ab[j];
    row.p_unchanged = ae[j];
    // At most one claim holds (each is read off the same ordered shift values, every critical
    // count above half of them); an inconclusive row's interval is at the smallest level of its
    // three failed steps, where none of the claims holds.
    const RowShift& s = *shifts[tested[j]];
    if (lw.made[j]) {
      set_verdict(row, s, "worse", lw.level[j]);
    } else if (lb.made[j]) {
      set_verdict(row, s, "better", lb.level[j]);
    } else if (le.made[j]) {
      set_verdict(row, s, "unchanged", le.level[j]);
    } else {
      set_verdict(row, s, "inconclusive", std::min({lw.level[j], lb.level[j], le.level[j]}));
    }
  }
}

std::vector<CompareRow> compare_samples(const std::vector<CompareSample>& rows,
                                        const CompareOptions& options) {
  if (!(options.alpha > 0.0 && options.alpha < 0.5) ||
      !(options.tolerance >= 0.0 && options.tolerance < 1.0))
    throw std::invalid_argument("compare_samples: alpha in (0, 0.5), tolerance in [0, 1)");
  std::vector<CompareRow> out(rows.size());
  std::vector<std::optional<RowShift>> shifts(rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const CompareSample& r = rows[i];
    for (const auto* v : {&r.base, &r.fresh}) {
      if (std::any_of(v->begin(), v->end(), [](double x) { return !(std::isfinite(x) && x >= 0); }))
        throw std::invalid_argument("compare_samples: " + r.name +
                                    ": a value that is negative or not finite");
    }
    if (r.paired && r.base.size() != r.fresh.size())
      throw std::invalid_argument("compare_samples: " + r.name + ": paired samples of " +
                                  std::to_string(r.base.size()) + " and " +
                                  std::to_string(r.fresh.size()) + " values");
    out[i].estimator = r.name;
    out[i].runs_base = r.base.size();
    out[i].runs_new = r.fresh.size();
    shifts[i] = test_values(r.base, r.fresh, r.paired, out[i]);
  }
  judge_family(out, shifts, options);
  return out;
}

}  // namespace ncosim::sim
