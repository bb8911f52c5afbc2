// sim/analysis/paired.cc — paired and Welch differences, Holm, the [paired] table, the paired
// columns.
#include "sim/analysis/paired.h"

#include <fmt/format.h>

#include <algorithm>
#include <boost/math/distributions/students_t.hpp>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>

#include "sim/files/csv.h"
#include "sim/scenario/scenario.h"

namespace ncosim::sim {

namespace {

struct Moments {
  double mean = 0.0, var = 0.0;  // sample variance (n - 1)
  std::size_t n = 0;
};

Moments moments(const std::vector<double>& v) {
  Moments m;
  m.n = v.size();
  if (m.n == 0) return m;
  for (double x : v) m.mean += x;
  m.mean /= static_cast<double>(m.n);
  if (m.n < 2) return m;
  double ss = 0.0;
  for (double x : v) ss += (x - m.mean) * (x - m.mean);
  m.var = ss / static_cast<double>(m.n - 1);
  return m;
}

bool all_finite(const std::vector<double>& v) {
  return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
}

// Welch-Satterthwaite degrees of freedom of a + b, a = va/na, b = vb/nb (variances of means).
double satterthwaite(double a, std::size_t na, double b, std::size_t nb) {
  const double num = (a + b) * (a + b);
  const double den = a * a / static_cast<double>(na - 1) + b * b / static_cast<double>(nb - 1);
  if (!(den > 0.0)) return static_cast<double>(na + nb - 2);
  return num / den;
}

// P(T > t) for Student t with `dof` degrees of freedom.
double upper_tail(double t, double dof) {
  if (std::isnan(t)) return 1.0;
  if (std::isinf(t)) return t > 0 ? 0.0 : 1.0;
  const boost::math::students_t dist(dof);
  return boost::math::cdf(boost::math::complement(dist, t));
}

// One-sided p-value of H1: E[x] > 0 from a mean and its standard error.
double p_positive(double mean, double se, double dof) {
  if (!(se > 0.0)) return mean > 0.0 ? 0.0 : 1.0;
  return upper_tail(mean / se, dof);
}

}  // namespace

double t_two_sided(double dof, double level) {
  const boost::math::students_t dist(dof);
  return boost::math::quantile(boost::math::complement(dist, (1.0 - level) / 2.0));
}

std::optional<Difference> paired_difference(const std::vector<double>& base,
                                            const std::vector<double>& fresh, double level) {
  const std::size_t n = base.size();
  if (n < 2 || fresh.size() != n || !all_finite(base) || !all_finite(fresh)) return std::nullopt;
  Difference d;
  d.paired = true;
  d.n_base = d.n_new = n;
  d.dof = static_cast<double>(n - 1);
  const Moments a = moments(base), b = moments(fresh);
  d.base_mean = a.mean;
  d.new_mean = b.mean;
  std::vector<double> diff(n);
  for (std::size_t i = 0; i < n; ++i) diff[i] = fresh[i] - base[i];
  const Moments md = moments(diff);
  const double t = t_two_sided(d.dof, level);
  d.diff = md.mean;
  d.diff_half = t * std::sqrt(md.var / static_cast<double>(n));
  if (a.mean != 0.0) {
    const double r = b.mean / a.mean;
    std::vector<double> z(n);
    for (std::size_t i = 0; i < n; ++i) z[i] = (fresh[i] - r * base[i]) / a.mean;
    d.ratio = r;
    d.ratio_half = t * std::sqrt(moments(z).var / static_cast<double>(n));
  }
  return d;
}

std::optional<Difference> welch_difference(const std::vector<double>& base,
                                           const std::vector<double>& fresh, double level) {
  if (base.size() < 2 || fresh.size() < 2 || !all_finite(base) || !all_finite(fresh))
    return std::nullopt;
  Difference d;
  d.n_base = base.size();
  d.n_new = fresh.size();
  const Moments a = moments(base), b = moments(fresh);
  d.base_mean = a.mean;
  d.new_mean = b.mean;
  const double va = a.var / static_cast<double>(a.n), vb = b.var / static_cast<double>(b.n);
  d.dof = satterthwaite(va, a.n, vb, b.n);
  d.diff = b.mean - a.mean;
  d.diff_half = t_two_sided(d.dof, level) * std::sqrt(va + vb);
  if (a.mean != 0.0) {
    const double r = b.mean / a.mean;
    // Delta method: Var(R) ~ (Var(mean new) + R^2 Var(mean base)) / mean(base)^2.
    const double dof_r = satterthwaite(vb, b.n, r * r * va, a.n);
    d.ratio = r;
    d.ratio_half = t_two_sided(dof_r, level) * std::sqrt(vb + r * r * va) / std::abs(a.mean);
  }
  return d;
}

RelativeTest relative_test(const std::vector<double>& base, const std::vector<double>& fresh,
                           bool paired, double margin) {
  RelativeTest r;
  auto one =
      [&](double factor) -> std::pair<double, double> {  // (estimate, se) of new - factor base
    if (paired) {
      std::vector<double> e(base.size());
      for (std::size_t i = 0; i < base.size(); ++i) e[i] = fresh[i] - factor * base[i];
      const Moments m = moments(e);
      return {m.mean, std::sqrt(m.var / static_cast<double>(m.n))};
    }
    const Moments a = moments(base), b = moments(fresh);
    return {b.mean - factor * a.mean,
            std::sqrt(b.var / static_cast<double>(b.n) +
                      factor * factor * a.var / static_cast<double>(a.n))};
  };
  auto dof = [&](double factor) {
    if (paired) return static_cast<double>(base.size() - 1);
    const Moments a = moments(base), b = moments(fresh);
    return satterthwaite(b.var / static_cast<double>(b.n), b.n,
                         factor * factor * a.var / static_cast<double>(a.n), a.n);
  };
  if (base.size() < 2 || fresh.size() < 2 || (paired && base.size() != fresh.size())) return r;
  const auto [ew, sw] = one(1.0 + margin);
  r.p_worse = p_positive(ew, sw, dof(1.0 + margin));
  const auto [eb, sb] = one(1.0 - margin);
  r.p_better = p_positive(-eb, sb, dof(1.0 - margin));
  return r;
}

std::vector<double> holm_adjust(const std::vector<double>& p) {
  const std::size_t k = p.size();
  std::vector<std::size_t> order(k);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return p[a] < p[b]; });
  std::vector<double> adj(k);
  double running = 0.0;
  for (std::size_t j = 0; j < k; ++j) {
    running = std::max(running, std::min(1.0, static_cast<double>(k - j) * p[order[j]]));
    adj[order[j]] = running;
  }
  return adj;
}

// ---- [paired]
// ------------------------------------------------------------------------------------

std::size_t reference_estimator_index(const Scenario& sc) {
  if (!sc.paired.reference.empty()) {
    for (std::size_t i = 0; i < sc.estimators.size(); ++i) {
      if (sc.estimators[i].name == sc.paired.reference) return i;
    }
  }
  for (std::size_t i = 0; i < sc.estimators.size(); ++i) {
    const auto& d = sc.estimators[i].design;
    if (d && d->is_kalman_reference()) return i;
  }
  return 0;
}

std::size_t reference_row_index(const Scenario& sc, const std::vector<SummaryRow>& rows) {
  const std::size_t fallback = reference_estimator_index(sc);
  if (!sc.paired.reference.empty() || rows.size() != sc.estimators.size()) return fallback;
  auto ok = [&](std::size_t i) { return rows[i].status == "ok"; };
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const auto& d = sc.estimators[i].design;
    if (d && d->is_kalman_reference() && ok(i)) return i;
  }
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (ok(i)) return i;
  }
  return fallback;
}

std::string paired_reference_note(const std::vector<SummaryRow>& rows) {
  std::string out;
  std::vector<std::vector<std::string>> cases;  // the cases already named
  for (const auto& r : rows) {
    if (r.estimator != r.paired.reference || !r.per_run.mse.empty()) continue;
    if (std::find(cases.begin(), cases.end(), r.sweep_labels) != cases.end()) continue;
    cases.push_back(r.sweep_labels);
    std::string where;
    for (const auto& l : r.sweep_labels) where += (where.empty() ? "" : ", ") + l;
    out += fmt::format(
        " The reference \"{}\"{} has status {}: no per-run mse to pair with, so its "
        "case's paired columns are empty.",
        r.estimator, where.empty() ? "" : " of the case " + where, r.status);
  }
  if (!out.empty()) out += " `[paired] reference` picks another row.";
  return out;
}

std::size_t reference_case_index(const LoadedScenario& loaded) {
  if (loaded.cases.empty()) return 0;
  const PairedSettings& p = loaded.cases.front().scenario->paired;
  if (p.reference_case.empty()) return 0;
  auto fail = [&](const std::string& msg) {
    throw config::ScenarioError(
        config::format_error(p.file, p.reference_case_line, "paired.reference_case", msg));
  };
  if (loaded.sweeps.empty())
    fail("expected [[sweep]] tables (a reference case names sweep values), got none");
  std::vector<std::size_t> idx(loaded.sweeps.size(), 0);
  for (const auto& [key, label] : p.reference_case) {
    std::size_t a = 0;
    while (a < loaded.sweeps.size() && loaded.sweeps[a].key != key) ++a;
    if (a == loaded.sweeps.size()) {
      std::vector<std::string> keys;
      std::string list;
      for (const auto& s : loaded.sweeps) {
        keys.push_back(s.key);
        list += (list.empty() ? "" : ", ") + fmt::format("\"{}\"", s.key);
      }
      const std::string hint = config::did_you_mean(key, keys);
      fail(fmt::format("expected a swept key path ({}), got \"{}\"{}", list, key,
                       hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint)));
    }
    const auto& labels = loaded.sweeps[a].labels;
    const auto it = std::find(labels.begin(), labels.end(), label);
    if (it == labels.end()) {
      std::string list;
      for (const auto& l : labels) list += (list.empty() ? "" : ", ") + l;
      fail(fmt::format("expected one of the values of \"{}\" ({}), got {}", key, list, label));
    }
    idx[a] = static_cast<std::size_t>(it - labels.begin());
  }
  std::size_t c = 0;
  for (std::size_t a = 0; a < idx.size(); ++a) c = c * loaded.sweeps[a].labels.size() + idx[a];
  return c < loaded.cases.size() ? c : 0;
}

// ---- summary columns -------------------------------------------------------------------------

namespace {

// The paired metric over the runs both rows have (matched by run index).
PairedMetric metric(const std::vector<double>& ref, const std::vector<std::uint64_t>& ref_run,
                    const std::vector<double>& row, const std::vector<std::uint64_t>& row_run) {
  PairedMetric m;
  if (ref.size() != ref_run.size() || row.size() != row_run.size()) return m;
  std::vector<double> a, b;
  if (ref_run == row_run) {
    a = ref;
    b = row;
  } else {
    std::map<std::uint64_t, double> by_run;
    for (std::size_t i = 0; i < row.size(); ++i) by_run[row_run[i]] = row[i];
    for (std::size_t i = 0; i < ref.size(); ++i) {
      const auto it = by_run.find(ref_run[i]);
      if (it == by_run.end()) continue;
      a.push_back(ref[i]);
      b.push_back(it->second);
    }
  }
  const auto d = paired_difference(a, b, 0.95);
  if (!d) return m;
  m.diff = d->diff;
  m.diff_ci95 = d->diff_half;
  m.ratio = d->ratio;
  m.ratio_ci95 = d->ratio_half;
  return m;
}

}  // namespace

void add_paired_within(std::vector<SummaryRow>& case_rows, std::size_t reference) {
  if (reference >= case_rows.size()) return;
  const SummaryRow& ref = case_rows[reference];
  for (std::size_t i = 0; i < case_rows.size(); ++i) {
    SummaryRow& row = case_rows[i];
    row.paired.reference = ref.estimator;
    if (i == reference) continue;
    const auto& ra = ref.per_run.run;
    const auto& rb = row.per_run.run;
    row.paired.mse = metric(ref.per_run.mse, ra, row.per_run.mse, rb);
    row.paired.mse_ext = metric(ref.per_run.mse_ext, ra, row.per_run.mse_ext, rb);
    row.paired.mde = metric(ref.per_run.mde, ra, row.per_run.mde, rb);
  }
}

void add_paired_across_cases(std::vector<SummaryRow>& rows, const LoadedScenario& loaded,
                             std::size_t reference_case) {
  if (loaded.sweeps.empty() || reference_case >= loaded.cases.size()) return;
  // Row ranges of each case.
  std::vector<std::size_t> start;
  std::size_t at = 0;
  for (const auto& c : loaded.cases) {
    start.push_back(at);
    at += c.scenario->estimators.size();
  }
  if (at != rows.size()) return;  // not the layout summarise() produced
  std::string where;
  for (std::size_t a = 0; a < loaded.sweeps.size(); ++a) {
    where += fmt::format("{}{}={}", a ? "; " : "", loaded.sweeps[a].key,
                         loaded.cases[reference_case].labels[a]);
  }
  const Scenario& ref_sc = *loaded.cases[reference_case].scenario;
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    const Scenario& sc = *loaded.cases[c].scenario;
    for (std::size_t e = 0; e < sc.estimators.size(); ++e) {
      SummaryRow& row = rows[start[c] + e];
      row.paired.reference_case = where;
      if (c == reference_case || sc.run.seed != ref_sc.run.seed) continue;
      for (std::size_t f = 0; f < ref_sc.estimators.size(); ++f) {
        if (ref_sc.estimators[f].name != row.estimator) continue;
        const SummaryRow& ref = rows[start[reference_case] + f];
        const auto& ra = ref.per_run.run;
        const auto& rb = row.per_run.run;
        row.paired.case_mse = metric(ref.per_run.mse, ra, row.per_run.mse, rb);
        row.paired.case_mse_ext = metric(ref.per_run.mse_ext, ra, row.per_run.mse_ext, rb);
        row.paired.case_mde = metric(ref.per_run.mde, ra, row.per_run.mde, rb);
      }
    }
  }
}

std::vector<std::string> paired_column_names(bool sweeps) {
  std::vector<std::string> cols{"paired_reference"};
  auto add = [&](const std::string& prefix) {
    for (const char* m : {"mse", "mse_ext", "mde"}) {
      for (const char* s : {"diff", "diff_ci95", "ratio", "ratio_ci95"}) {
        cols.push_back(fmt::format("{}{}_{}", prefix, m, s));
      }
    }
  };
  add("");
  if (sweeps) {
    cols.emplace_back("reference_case");
    add("case_");
  }
  return cols;
}

std::vector<std::string> paired_cells(const PairedColumns& p, bool sweeps) {
  std::vector<std::string> cells{p.reference};
  auto add = [&](const PairedMetric& m) {
    for (const auto& v : {m.diff, m.diff_ci95, m.ratio, m.ratio_ci95})
      cells.push_back(fmt_number(v));
  };
  add(p.mse);
  add(p.mse_ext);
  add(p.mde);
  if (sweeps) {
    cells.push_back(p.reference_case);
    add(p.case_mse);
    add(p.case_mse_ext);
    add(p.case_mde);
  }
  return cells;
}

}  // namespace ncosim::sim
