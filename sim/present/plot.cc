// sim/present/plot.cc — `ncosim plot`: summary and trace figures through gnuplot (.dat + .gp +
// images; gnuplot itself is run by sim/present/plot_render.cc).
#include "sim/present/plot.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <vector>

#include "config/config.h"
#include "sim/analysis/output.h"
#include "sim/present/plot_trace.h"

namespace ncosim::sim {

namespace fs = std::filesystem;
using namespace figure_text;  // sim/present/figure.h

namespace {

// The summary as the figures see it: sweep keys, cases in file order, estimators in order.
struct Summary {
  CsvTable t;
  std::vector<std::string> keys;        // sweep key columns (before `estimator`)
  std::vector<std::string> estimators;  // in order of first appearance
  int est_col = -1;
};

Summary read_summary(const std::string& dir) {
  const fs::path p = fs::path(dir) / "summary.csv";
  Summary s;
  s.t = parse_csv(read_file(p), p.string());
  s.est_col = s.t.column("estimator");
  if (s.est_col < 0)
    throw config::ScenarioError(
        config::format_error(p.string(), 1, "", "expected an `estimator` column"));
  for (int i = 0; i < s.est_col; ++i) s.keys.push_back(s.t.header[static_cast<std::size_t>(i)]);
  for (const auto& r : s.t.rows) {
    const auto& e = r[static_cast<std::size_t>(s.est_col)];
    if (std::find(s.estimators.begin(), s.estimators.end(), e) == s.estimators.end())
      s.estimators.push_back(e);
  }
  return s;
}

// Distinct values of a column, in order of first appearance.
std::vector<std::string> distinct(const CsvTable& t, int col) {
  std::vector<std::string> out;
  for (const auto& r : t.rows) {
    const auto& v = r[static_cast<std::size_t>(col)];
    if (std::find(out.begin(), out.end(), v) == out.end()) out.push_back(v);
  }
  return out;
}

bool all_numeric(const std::vector<std::string>& values) {
  return std::all_of(values.begin(), values.end(),
                     [](const std::string& v) { return number(v).has_value(); });
}

std::string prediction_column(const CsvTable& t, const std::string& metric) {
  const std::string p = metric == "mse" ? "predicted_mse" : "predicted_" + metric;
  return t.column(p) >= 0 ? p : "";
}

struct Choice {
  FigureKind kind = FigureKind::kPerEstimator;
  std::string x_key;
  std::vector<std::string> panel_keys;
};

Choice choose(const Summary& s, const PlotOptions& opt, const std::string& what) {
  Choice c;
  auto check_key = [&](const std::string& k, const char* option) {
    if (std::find(s.keys.begin(), s.keys.end(), k) == s.keys.end()) {
      std::string valid;
      for (const auto& v : s.keys) valid += (valid.empty() ? "" : ", ") + v;
      throw config::ScenarioError(
          fmt::format("{} '{}': not a sweep key of {} (sweep keys: {})", option, k, what,
                      valid.empty() ? "none, the campaign has one case" : valid));
    }
  };
  if (!opt.x_key.empty()) check_key(opt.x_key, "--x");
  if (!opt.panel_key.empty()) check_key(opt.panel_key, "--panel");
  if (!opt.x_key.empty() && opt.x_key == opt.panel_key) {
    throw config::ScenarioError(
        fmt::format("--panel '{}': expected a key other than the x key", opt.panel_key));
  }
  if (s.keys.empty()) return c;
  c.x_key = opt.x_key;
  if (c.x_key.empty()) {
    for (const auto& k : s.keys) {
      if (k != opt.panel_key && all_numeric(distinct(s.t, s.t.column(k)))) {
        c.x_key = k;
        break;
      }
    }
    if (c.x_key.empty()) {
      for (const auto& k : s.keys) {
        if (k != opt.panel_key) {
          c.x_key = k;
          break;
        }
      }
    }
  }
  if (!opt.panel_key.empty()) {
    c.panel_keys = {opt.panel_key};
  } else {
    for (const auto& k : s.keys) {
      if (k != c.x_key) c.panel_keys.push_back(k);
    }
  }
  c.kind = c.panel_keys.empty() ? FigureKind::kAgainstKey : FigureKind::kPanels;
  return c;
}

struct Range {
  double lo = INFINITY, hi = -INFINITY, min_positive = INFINITY;
  bool any_nonpositive = false;
  void add(double v) {
    lo = std::min(lo, v);
    hi = std::max(hi, v);
    if (v > 0) {
      min_positive = std::min(min_positive, v);
    } else {
      any_nonpositive = true;
    }
  }
  bool empty() const { return !(lo <= hi); }
};

bool want_log(const std::string& mode, const Range& r, const char* option) {
  if (mode == "on") return true;
  if (mode == "off") return false;
  if (mode != "auto")
    throw config::ScenarioError(fmt::format("{} '{}': expected auto, on or off", option, mode));
  return !r.empty() && !r.any_nonpositive && r.hi / r.lo >= 100.0;
}

std::string palette_style(std::size_t e) {
  static const char* colours[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e",
                                  "#17becf", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22"};
  return fmt::format("lc rgb '{}' pt {}", colours[e % 10], 1 + static_cast<int>(e % 13));
}

// Lower end of an error bar on a log axis: a CI reaching below zero is drawn to y/1000.
std::string errorbar_using(const std::string& x, bool ci, bool log) {
  if (!ci) return fmt::format("{}:2", x);
  if (log) return fmt::format("{}:2:($2-$3 > 0 ? $2-$3 : $2*1e-3):($2+$3)", x);
  return fmt::format("{}:2:($2-$3):($2+$3)", x);
}

// The columns of summary.csv that one summary figure reads.
struct MetricColumns {
  std::string metric;
  int value = -1;  // the metric
  int ci = -1;     // <metric>_ci95, -1 when absent
  int pred = -1;   // the prediction of the metric (prediction_column), -1 when absent
  std::string pred_name;
  // A paired-difference column (`mse_diff`, ...): each row minus its reference estimator on the
  // same runs (results/README.md, "Paired columns"); zero line, linear axis, reference named.
  bool paired = false;
};

// The columns of `metric`; throws naming the columns that could be plotted when it is not one.
MetricColumns metric_columns(const Summary& s, const std::string& metric, const std::string& what) {
  MetricColumns mc;
  mc.metric = metric;
  mc.value = s.t.column(metric);
  if (mc.value < 0 || mc.value <= s.est_col + 1) {
    std::string valid;
    for (std::size_t i = static_cast<std::size_t>(s.est_col) + 2; i < s.t.header.size(); ++i) {
      const auto& h = s.t.header[i];
      if (h != "status" && h.find("_ci95") == std::string::npos)
        valid += (valid.empty() ? "" : ", ") + h;
    }
    throw config::ScenarioError(
        fmt::format("--metric '{}': not a column of {} (columns: {})", metric, what, valid));
  }
  mc.ci = s.t.column(metric + "_ci95");
  // A CI column without a single value (one run: no spread) is drawn as absent: error bars of
  // '?' only would be a series without a valid point (a gnuplot warning, and the points missing).
  if (mc.ci >= 0 && std::none_of(s.t.rows.begin(), s.t.rows.end(), [&](const auto& r) {
        return number(r[static_cast<std::size_t>(mc.ci)]).has_value();
      })) {
    mc.ci = -1;
  }
  mc.pred_name = prediction_column(s.t, metric);
  mc.pred = mc.pred_name.empty() ? -1 : s.t.column(mc.pred_name);
  mc.paired = metric.size() > 5 && metric.ends_with("_diff") && s.t.column("paired_reference") >= 0;
  return mc;
}

// The names of the metric's three .dat columns ('-' for an absent one).
std::string dat_metric_names(const MetricColumns& mc) {
  return fmt::format("{} {} {}", mc.metric, mc.ci >= 0 ? mc.metric + "_ci95" : "-",
                     mc.pred >= 0 ? mc.pred_name : "-");
}

// The metric's three .dat fields of row r: value, CI half-width, prediction ('?' when absent).
std::string dat_metric_fields(const std::vector<std::string>& r, const MetricColumns& mc) {
  return fmt::format("{} {} {}", dat_field(r[static_cast<std::size_t>(mc.value)]),
                     mc.ci >= 0 ? dat_field(r[static_cast<std::size_t>(mc.ci)]) : "?",
                     mc.pred >= 0 ? dat_field(r[static_cast<std::size_t>(mc.pred)]) : "?");
}

// The summary figure's title: the metric, its CI, the runs and the scenario's title; a paired
// difference names its reference estimator(s).
std::string summary_title(const Summary& s, const MetricColumns& mc, const std::string& scenario) {
  const int runs = s.t.column("runs");
  std::string runs_text;
  if (runs >= 0 && !s.t.rows.empty())
    runs_text = fmt::format(", {} runs", s.t.rows.front()[static_cast<std::size_t>(runs)]);
  const std::string tail = scenario.empty() ? "" : " — " + scenario;
  if (!mc.paired)
    return fmt::format("{}{}{}{}", mc.metric, mc.ci >= 0 ? " with 95 % CI" : "", runs_text, tail);
  std::string reference;
  for (const auto& r : distinct(s.t, s.t.column("paired_reference")))
    reference += (reference.empty() ? "" : ", ") + r;
  const std::string base_metric = mc.metric.substr(0, mc.metric.size() - 5);
  return fmt::format("paired {0}: {0} − {0} of the reference ({1}) on the same runs{2}{3}{4}",
                     base_metric, reference, mc.ci >= 0 ? ", 95 % CI" : "", runs_text, tail);
}

// The y values the figure shows: the metric, the ends of its CI (the lower end when positive,
// or always for a paired difference) and the prediction.
Range y_range(const Summary& s, const MetricColumns& mc) {
  Range yr;
  for (const auto& r : s.t.rows) {
    const auto v = number(r[static_cast<std::size_t>(mc.value)]);
    if (!v) continue;
    yr.add(*v);
    if (mc.ci >= 0) {
      if (const auto h = number(r[static_cast<std::size_t>(mc.ci)])) {
        yr.add(*v + *h);
        if (*v - *h > 0 || mc.paired) yr.add(*v - *h);
      }
    }
    if (mc.pred >= 0) {
      if (const auto p = number(r[static_cast<std::size_t>(mc.pred)])) yr.add(*p);
    }
  }
  return yr;
}

// A summary figure before `script` wraps it: the .dat text, the gnuplot body, the image size.
struct SummaryPlot {
  std::string dat, body;
  int width = 900, height = 560;
};

// Without sweep keys: one point per row of summary.csv, the estimators along x.
void plot_per_estimator(const Summary& s, const MetricColumns& mc, const std::string& name,
                        bool logy, SummaryPlot& p) {
  bool any_pred = false;
  for (const auto& r : s.t.rows)
    any_pred = any_pred || (mc.pred >= 0 && number(r[static_cast<std::size_t>(mc.pred)]));
  p.dat += fmt::format("# index {}   (index: estimator, named in the comment above its row)\n",
                       dat_metric_names(mc));
  for (std::size_t e = 0; e < s.t.rows.size(); ++e) {
    const auto& r = s.t.rows[e];
    p.dat += fmt::format("# {}\n{} {}\n", comment(r[static_cast<std::size_t>(s.est_col)]), e,
                         dat_metric_fields(r, mc));
  }
  p.width = std::max(700, 110 * static_cast<int>(s.t.rows.size()) + 250);
  std::vector<std::string> labels;
  for (const auto& r : s.t.rows) {
    const auto& est = r[static_cast<std::size_t>(s.est_col)];
    const bool is_reference =
        mc.paired && est == r[static_cast<std::size_t>(s.t.column("paired_reference"))];
    labels.push_back(est + (number(r[static_cast<std::size_t>(mc.value)]) ? ""
                            : is_reference                                ? " (reference)"
                                           : " (no " + mc.metric + ")"));
  }
  p.body += fmt::format("  set xtics rotate by -25 {}\n  set xrange [-0.6:{}]\n  set bmargin 9\n",
                        tics(labels), static_cast<double>(s.t.rows.size()) - 0.4);
  p.body += "  set key outside bottom center horizontal\n";
  const bool any_value = std::any_of(s.t.rows.begin(), s.t.rows.end(), [&](const auto& r) {
    return number(r[static_cast<std::size_t>(mc.value)]).has_value();
  });
  if (!any_value) {  // no point to draw (gnuplot would warn): say so in the figure
    p.body += fmt::format(
        "  set label 1 {} at graph 0.5, graph 0.5 center\n  set yrange [1:10]\n  plot 1/0 "
        "notitle\n",
        gnuplot_quote(fmt::format("no finite {} in any row", mc.metric)));
    return;
  }
  p.body +=
      fmt::format("  plot '{}.dat' using {} with {} pt 7 ps 1.2 lc rgb '#1f77b4' title {}", name,
                  errorbar_using("1", mc.ci >= 0, logy), mc.ci >= 0 ? "yerrorbars" : "points",
                  gnuplot_quote(mc.ci >= 0 ? "simulated, 95 % CI" : "simulated"));
  if (any_pred) {
    p.body += fmt::format(
        ", \\\n       '' using ($1+0.2):4 with points pt 4 ps 1.5 lc rgb '#d62728' title {}",
        gnuplot_quote("predicted (" + mc.pred_name + ")"));
  }
  p.body += "\n";
}

// Above this many rows a one-case figure lists the estimators down the y axis (a dot plot, every
// label horizontal and readable, the figure growing in height) instead of along x (a figure
// growing in width: 32 rows were 3770 px, shrunk on a page until no label could be read).
constexpr std::size_t kMostRowsAcross = 12;

// A title as a gnuplot string expression on two lines, broken before the scenario's title
// (" — "), so that a long one fits a 900-px figure.
std::string two_line_title(const std::string& title) {
  const auto at = title.find(" — ");
  if (at == std::string::npos) return gnuplot_quote(title);
  return gnuplot_quote(title.substr(0, at)) + ".\"\\n\"." +
         gnuplot_quote(title.substr(at + std::string(" — ").size()));
}

// Without sweep keys, many rows: one line per row of summary.csv, the estimators down the y
// axis (first on top), the metric along x with its CI as a horizontal bar, the prediction as a
// square on the same line.
void plot_rows_down(const Summary& s, const MetricColumns& mc, const std::string& name, bool logx,
                    SummaryPlot& p) {
  const std::size_t n = s.t.rows.size();
  bool any_pred = false, any_value = false;
  p.dat += fmt::format("# index {}   (index: estimator, named in the comment above its row)\n",
                       dat_metric_names(mc));
  std::vector<std::string> labels;
  for (std::size_t e = 0; e < n; ++e) {
    const auto& r = s.t.rows[e];
    const auto& est = r[static_cast<std::size_t>(s.est_col)];
    p.dat += fmt::format("# {}\n{} {}\n", comment(est), e, dat_metric_fields(r, mc));
    any_pred = any_pred || (mc.pred >= 0 && number(r[static_cast<std::size_t>(mc.pred)]));
    const bool value = number(r[static_cast<std::size_t>(mc.value)]).has_value();
    any_value = any_value || value;
    const bool is_reference =
        mc.paired && est == r[static_cast<std::size_t>(s.t.column("paired_reference"))];
    labels.push_back(est + (value          ? ""
                            : is_reference ? " (reference)"
                                           : " (no " + mc.metric + ")"));
  }
  p.width = 900;
  p.height = 22 * static_cast<int>(n) + 190;
  p.body += fmt::format("  set ytics {}\n  set yrange [{}:-0.6]\n  unset ylabel\n", tics(labels),
                        static_cast<double>(n) - 0.4);
  p.body += "  set key outside bottom center horizontal\n";
  if (!any_value) {
    p.body += fmt::format(
        "  set label 1 {} at graph 0.5, graph 0.5 center\n  set xrange [1:10]\n  plot 1/0 "
        "notitle\n",
        gnuplot_quote(fmt::format("no finite {} in any row", mc.metric)));
    return;
  }
  const std::string x = mc.ci < 0 ? "2:1"
                        : logx    ? "2:1:($2-$3 > 0 ? $2-$3 : $2*1e-3):($2+$3)"
                                  : "2:1:($2-$3):($2+$3)";
  p.body += fmt::format("  plot '{}.dat' using {} with {} pt 7 ps 1.0 lc rgb '#1f77b4' title {}",
                        name, x, mc.ci >= 0 ? "xerrorbars" : "points",
                        gnuplot_quote(mc.ci >= 0 ? "simulated, 95 % CI" : "simulated"));
  if (any_pred) {
    p.body += fmt::format(
        ", \\\n       '' using 4:($1+0.25) with points pt 4 ps 1.2 lc rgb '#d62728' title {}",
        gnuplot_quote("predicted (" + mc.pred_name + ")"));
  }
  p.body += "\n";
}

// The x axis and the panels of a figure against a sweep key.
struct KeyAxes {
  std::string x_key;
  int x_col = -1;
  std::vector<std::string> xs;  // distinct x values in file order
  bool numeric_x = false, logx = false;
  std::vector<std::string> panel_keys;
  std::vector<int> panel_cols;
  std::vector<std::string> panels;  // panel labels in order of first appearance

  // The panel label of row r: "key = value, ..." over the panel keys ("" without panel keys).
  std::string panel_of(const std::vector<std::string>& r) const {
    std::string label;
    for (std::size_t i = 0; i < panel_cols.size(); ++i) {
      label += fmt::format("{}{} = {}", i ? ", " : "", panel_keys[i],
                           r[static_cast<std::size_t>(panel_cols[i])]);
    }
    return label;
  }
};

KeyAxes key_axes(const Summary& s, const Choice& c, const std::string& logx_mode) {
  KeyAxes a;
  a.x_key = c.x_key;
  a.x_col = s.t.column(c.x_key);
  a.xs = distinct(s.t, a.x_col);
  a.numeric_x = all_numeric(a.xs);
  Range xr;
  if (a.numeric_x) {
    for (const auto& v : a.xs) xr.add(*number(v));
  }
  a.logx = a.numeric_x && want_log(logx_mode, xr, "--logx");
  a.panel_keys = c.panel_keys;
  for (const auto& k : c.panel_keys) a.panel_cols.push_back(s.t.column(k));
  for (const auto& r : s.t.rows) {
    const std::string p = a.panel_of(r);
    if (std::find(a.panels.begin(), a.panels.end(), p) == a.panels.end()) a.panels.push_back(p);
  }
  return a;
}

// The .dat of a figure against a key: one block per panel and estimator, in that order
// (gnuplot's `index` = panel * estimators + estimator), "? ? ? ?" for a block without rows.
std::string against_key_dat(const Summary& s, const MetricColumns& mc, const KeyAxes& a) {
  std::string dat =
      fmt::format("# x {}   (one block per {}estimator; x = {}{})\n", dat_metric_names(mc),
                  a.panels.size() > 1 ? "panel and " : "", comment(a.x_key),
                  a.numeric_x ? "" : ", as the index of its value in the figure's x tics");
  std::size_t block = 0;
  for (const auto& p : a.panels) {
    for (const auto& e : s.estimators) {
      if (block++ > 0) dat += "\n\n";
      dat += fmt::format("# block {}: {}{}\n", block - 1, p.empty() ? "" : comment(p) + ", ",
                         comment(e));
      bool wrote = false;
      for (const auto& r : s.t.rows) {
        if (r[static_cast<std::size_t>(s.est_col)] != e || a.panel_of(r) != p) continue;
        const auto& xv = r[static_cast<std::size_t>(a.x_col)];
        const std::string x =
            a.numeric_x ? xv
                        : std::to_string(std::find(a.xs.begin(), a.xs.end(), xv) - a.xs.begin());
        dat += fmt::format("{} {}\n", x, dat_metric_fields(r, mc));
        wrote = true;
      }
      if (!wrote) dat += "? ? ? ?\n";
    }
  }
  return dat;
}

// What panel p holds of estimator e: a finite value, a finite prediction, and the first status
// that is not ok (why a series without finite values is empty).
struct BlockContent {
  bool value = false, pred = false;
  std::string status;
};

BlockContent block_content(const Summary& s, const MetricColumns& mc, const KeyAxes& a,
                           std::size_t p, std::size_t e) {
  BlockContent b;
  const int st = s.t.column("status");
  for (const auto& r : s.t.rows) {
    if (r[static_cast<std::size_t>(s.est_col)] != s.estimators[e] || a.panel_of(r) != a.panels[p])
      continue;
    b.value = b.value || number(r[static_cast<std::size_t>(mc.value)]).has_value();
    b.pred = b.pred || (mc.pred >= 0 && number(r[static_cast<std::size_t>(mc.pred)]).has_value());
    if (b.status.empty() && st >= 0 && r[static_cast<std::size_t>(st)] != "ok")
      b.status = r[static_cast<std::size_t>(st)];
  }
  return b;
}

// A legend entry (no data) saying why a series is not drawn: gnuplot warns about a data series
// without a valid point ("Skipping data file with no valid points"), so an empty one is left out.
std::string empty_series_entry(const std::string& label, const std::string& metric,
                               const std::string& status, const std::string& style) {
  return fmt::format("keyentry with points {} title {}", style,
                     gnuplot_quote(fmt::format("{}: no finite {}{}", label, metric,
                                               status.empty() ? "" : ": " + status)));
}

// The `plot` command of panel p: one curve per estimator, its prediction dashed in the same colour;
// an estimator without a finite value in the panel is a legend entry saying so, and a panel with
// nothing to draw says so in its middle (its y range fixed, so that gnuplot has one).
// Only the estimators [lo, hi) (a group of at most kMostSeries): their colours are their places in
// the group, so that no colour repeats within a panel.
std::string panel_plot(const Summary& s, const MetricColumns& mc, const KeyAxes& a,
                       const std::string& name, bool logy, std::size_t p, bool shared_yrange,
                       std::size_t lo, std::size_t hi) {
  const std::size_t E = s.estimators.size();
  std::string plot;
  bool drawn = false;
  for (std::size_t e = lo; e < hi; ++e) {
    const std::size_t b = p * E + e;
    const BlockContent bc = block_content(s, mc, a, p, e);
    const std::string sep = plot.empty() ? "" : ", \\\n       ";
    if (!bc.value) {
      plot +=
          sep + empty_series_entry(s.estimators[e], mc.metric, bc.status, palette_style(e - lo));
      continue;
    }
    drawn = true;
    // Categorical x: estimators side by side around each tic so their bars do not overlap.
    const std::string x =
        a.numeric_x ? "1"
                    : fmt::format("($1{:+.3f})", (static_cast<double>(e) - (E - 1) / 2.0) * 0.06);
    plot +=
        fmt::format("{}'{}.dat' index {} using {} with {} {} ps 1.0 title {}", sep, name, b,
                    errorbar_using(x, mc.ci >= 0, logy), mc.ci >= 0 ? "yerrorlines" : "linespoints",
                    palette_style(e - lo), gnuplot_quote(s.estimators[e]));
    if (bc.pred) {
      plot += fmt::format(", \\\n       '' index {} using {}:4 with lines dt 2 {} title {}", b, x,
                          gnuplot_colour(e - lo), gnuplot_quote(s.estimators[e] + ", predicted"));
    }
  }
  if (drawn) return "  plot " + plot + "\n";
  std::string h = fmt::format("  set label 1 {} at graph 0.5, graph 0.5 center\n",
                              gnuplot_quote(fmt::format("no finite {} in this panel", mc.metric)));
  if (!shared_yrange) h += "  set yrange [1:10]\n";
  h += "  plot " + plot + ", \\\n       1/0 notitle\n  unset label 1\n";
  if (!shared_yrange) h += "  set autoscale y\n";
  return h;
}

// Against a sweep key: one curve per estimator, in one panel per value of the panel keys (a
// grid of up to 3 columns sharing one y range); more than kMostSeries estimators are split into
// groups of at most kGroupSeries, one panel per group and value (every colour distinct within a
// panel).
void plot_against_key(const Summary& s, const MetricColumns& mc, const Choice& c,
                      const PlotOptions& opt, const std::string& name, const std::string& title,
                      const Range& yr, bool logy, SummaryPlot& p) {
  const KeyAxes a = key_axes(s, c, opt.logx);
  p.dat += against_key_dat(s, mc, a);
  const std::size_t E = s.estimators.size();
  const std::size_t G = series_groups(E);
  const std::size_t P = a.panels.size() * G;
  const std::size_t cols =
      P == 1 ? 1 : std::min<std::size_t>(3, static_cast<std::size_t>(std::ceil(std::sqrt(P))));
  const std::size_t rows = (P + cols - 1) / cols;
  p.width = P == 1 ? 900 : static_cast<int>(cols) * 520;
  p.height = P == 1 ? 560 : static_cast<int>(rows) * 400 + 60;
  p.body += fmt::format("  set xlabel {}\n", gnuplot_quote(a.x_key));
  if (a.logx) p.body += "  set logscale x\n";
  if (a.numeric_x)
    p.body += "  set offsets graph 0.03, graph 0.03, 0, 0\n";  // end points' bars inside the frame
  if (!a.numeric_x) {
    p.body += fmt::format("  set xtics {}\n  set xrange [-0.5:{}]\n", tics(a.xs),
                          static_cast<double>(a.xs.size()) - 0.5);
  }
  if (P > 1 && !yr.empty()) {  // one y range for every panel, so that panels compare
    const double lo = logy ? yr.min_positive / 1.5 : yr.lo - 0.05 * (yr.hi - yr.lo);
    const double hi = logy ? yr.hi * 1.5 : yr.hi + 0.05 * (yr.hi - yr.lo);
    if (hi > lo) p.body += fmt::format("  set yrange [{:.6g}:{:.6g}]\n", lo, hi);
  }
  if (P > 1) {
    p.body +=
        fmt::format("  set multiplot layout {},{} title {}\n", rows, cols, gnuplot_quote(title));
    p.body += "  set key top left font ',8' box opaque\n";
  } else {
    p.body += "  set key outside right top\n";
  }
  const bool shared_yrange = P > 1 && !yr.empty();
  for (std::size_t i = 0; i < P; ++i) {
    const std::size_t panel = i / G, g = i % G;
    const std::size_t lo = g * E / G, hi = (g + 1) * E / G;
    if (P > 1) {
      std::string t = a.panels[panel];
      if (G > 1)
        t += fmt::format("{}estimators {}–{} of {}", t.empty() ? "" : " · ", lo + 1, hi, E);
      p.body += fmt::format("  set title {}\n", gnuplot_quote(t));
      if (i == 1 && G == 1) p.body += "  unset key\n";  // every panel the same estimators
    }
    p.body += panel_plot(s, mc, a, name, logy, panel, shared_yrange, lo, hi);
  }
}

Figure summary_figure(const std::string& dir, const Summary& s, const PlotOptions& opt) {
  const std::string what = (fs::path(dir) / "summary.csv").string();
  const MetricColumns mc = metric_columns(s, opt.metric, what);
  const Choice c = choose(s, opt, what);

  Figure f;
  f.name = "plot_" + opt.metric;
  f.kind = c.kind;
  f.title = summary_title(s, mc, scenario_title(dir));
  const Range yr = y_range(s, mc);
  const bool logy = !mc.paired && want_log(opt.logy, yr, "--logy");
  // Many rows of one case: the metric along x, the rows down the y axis (plot_rows_down).
  const bool rows_down = c.kind == FigureKind::kPerEstimator && s.t.rows.size() > kMostRowsAcross;
  const char* axis = rows_down ? "x" : "y";

  SummaryPlot p;
  p.dat = fmt::format("# {} — numbers copied from summary.csv as written ('?' = empty)\n",
                      comment(f.title));
  p.body = fmt::format("  set title {}\n  set {}label {}\n  set grid\n",
                       rows_down ? two_line_title(f.title) : gnuplot_quote(f.title), axis,
                       gnuplot_quote(opt.metric + (mc.ci >= 0 ? "  (bars: 95 % CI)" : "")));
  if (logy) p.body += fmt::format("  set logscale {}\n", axis);
  if (mc.paired) p.body += fmt::format("  set {}zeroaxis lt -1 lw 1.5\n", rows_down ? "y" : "x");
  if (rows_down) {
    plot_rows_down(s, mc, f.name, logy, p);
  } else if (c.kind == FigureKind::kPerEstimator) {
    plot_per_estimator(s, mc, f.name, logy, p);
  } else {
    plot_against_key(s, mc, c, opt, f.name, f.title, yr, logy, p);
  }
  f.dat = p.dat;
  f.gp = gnuplot_script(f.name, f.title, p.width, p.height, p.body);
  return f;
}

}  // namespace

FigureKind summary_figure_kind(const CsvTable& summary, const PlotOptions& opt) {
  Summary s;
  s.t = summary;
  s.est_col = s.t.column("estimator");
  for (int i = 0; i < s.est_col; ++i) s.keys.push_back(s.t.header[static_cast<std::size_t>(i)]);
  return choose(s, opt, "summary.csv").kind;
}

std::vector<Figure> build_figures(const std::string& dir, const PlotOptions& opt) {
  if (!fs::is_directory(dir)) throw config::ScenarioError(fmt::format("{}: not a directory", dir));
  std::vector<Figure> out;
  const Summary s = read_summary(dir);
  out.push_back(summary_figure(dir, s, opt));
  // The paired differences against the reference estimator, when summary.csv has them for this
  // metric and any row has a value (a second figure, `plot_<metric>_diff`).
  const int diff = s.t.column(opt.metric + "_diff");
  if (!opt.metric.ends_with("_diff") && diff >= 0 &&
      std::any_of(s.t.rows.begin(), s.t.rows.end(), [&](const auto& r) {
        return number(r[static_cast<std::size_t>(diff)]).has_value();
      })) {
    PlotOptions po = opt;
    po.metric += "_diff";
    out.push_back(summary_figure(dir, s, po));
  }
  if (opt.trace) out.push_back(trace_figure(dir, opt));
  if (auto curve = error_curve_figure(dir)) out.push_back(std::move(*curve));
  return out;
}

int plot_command(const std::string& dir, const PlotOptions& opt) {
  for (const auto& f : opt.formats) {
    if (f != "png" && f != "svg")
      throw config::ScenarioError(fmt::format("--format '{}': expected png or svg", f));
  }
  const auto figures = build_figures(dir, opt);
  const auto images = render_figures(dir, figures, opt.formats);
  for (const auto& f : figures) {
    std::cout << fmt::format("{:<14} {}: {}.dat, {}.gp", figure_kind_name(f.kind), f.title, f.name,
                             f.name);
    for (const auto& x : opt.formats) std::cout << fmt::format(", {}.{}", f.name, x);
    std::cout << "\n";
  }
  std::cout << fmt::format("written to {}/\n", dir);
  return 0;
}

}  // namespace ncosim::sim
