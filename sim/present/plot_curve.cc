// sim/present/plot_curve.cc — the error-curve figure of `ncosim plot`: error_curve.csv ([run]
// error_curve) as one curve per estimator against the period, its 95 % band shaded, one panel
// per case (and per group of at most kGroupSeries estimators when a case has more than
// kMostSeries, so that no colour repeats within a panel). The numbers are copied from the CSV as
// written, at most kMostPoints periods per series (every k-th period and the last: the figure
// stays small however long the run; the .dat says which k). Values above 1e150 are drawn as
// missing; a series without a single drawable value is left out and named in its panel's title,
// so gnuplot never meets an empty series; a series whose row diverged (summary.csv's status) is
// drawn but left out of its panel's y range (the other series' range) and says so in the legend
// ("(diverged, off the scale)").
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "config/config.h"
#include "sim/files/csv.h"
#include "sim/present/plot.h"

namespace ncosim::sim {

namespace {

constexpr std::size_t kMaxPanels = 8;
// Values above this are drawn as missing: the run recorder's divergence threshold (|e|^2 > 1e150),
// and far beyond it gnuplot's axis range overflows ("y axis range undefined or overflow").
constexpr double kLargest = 1e150;
// The most periods drawn per series (a 20000-period campaign of 32 estimators made a 6 MB figure).
constexpr std::size_t kMostPoints = 400;

struct Series {
  std::string estimator;
  std::vector<std::array<double, 3>> points;  // period, mean, half-width (NaN: none)
  bool diverged = false;                      // its row's status in summary.csv
};

struct Panel {
  std::string label;  // the case's sweep values ("" for one case)
  std::vector<Series> series;
};

// What one panel of the figure shows: the series [lo, hi) of a case.
struct View {
  const Panel* panel = nullptr;
  std::size_t lo = 0, hi = 0;
  std::string title() const {
    const std::size_t n = panel->series.size();
    if (lo == 0 && hi == n) return panel->label;
    return fmt::format("{}estimators {}–{} of {}", panel->label.empty() ? "" : panel->label + " · ",
                       lo + 1, hi, n);
  }
};

double parse(const std::string& s) {
  if (s.empty()) return std::nan("");
  try {
    std::size_t used = 0;
    const double v = std::stod(s, &used);
    return used == s.size() ? v : std::nan("");
  } catch (...) {
    return std::nan("");
  }
}

// "key = value, ..." of the columns before `estimator` in row r.
std::string case_label(const CsvTable& t, int est, const std::vector<std::string>& r) {
  std::string label;
  for (int i = 0; i < est; ++i) {
    label += fmt::format("{}{} = {}", i ? ", " : "", t.header[static_cast<std::size_t>(i)],
                         r[static_cast<std::size_t>(i)]);
  }
  return label;
}

std::vector<Panel> read_panels(const CsvTable& t) {
  const int est = t.column("estimator"), period = t.column("period"), mse = t.column("mse"),
            ci = t.column("mse_ci95");
  if (est < 0 || period < 0 || mse < 0 || ci < 0) {
    throw config::ScenarioError(
        "error_curve.csv: expected the columns estimator, period, mse and mse_ci95");
  }
  std::vector<Panel> panels;
  for (const auto& r : t.rows) {
    const std::string label = case_label(t, est, r);
    if (panels.empty() || panels.back().label != label) panels.push_back(Panel{label, {}});
    auto& series = panels.back().series;
    const std::string& name = r[static_cast<std::size_t>(est)];
    if (series.empty() || series.back().estimator != name) series.push_back(Series{name, {}});
    series.back().points.push_back({parse(r[static_cast<std::size_t>(period)]),
                                    parse(r[static_cast<std::size_t>(mse)]),
                                    parse(r[static_cast<std::size_t>(ci)])});
  }
  return panels;
}

// Marks the series whose row in DIR/summary.csv (same case label, same estimator) diverged:
// status `diverged`, or no mse (a run diverged; a failed design's status takes precedence).
void mark_diverged(const std::filesystem::path& dir, std::vector<Panel>& panels) {
  std::ifstream in(dir / "summary.csv", std::ios::binary);
  if (!in) return;
  std::stringstream text;
  text << in.rdbuf();
  const CsvTable t = parse_csv(text.str(), (dir / "summary.csv").string());
  const int est = t.column("estimator"), status = t.column("status"), mse = t.column("mse");
  if (est < 0 || status < 0 || mse < 0) return;
  for (const auto& r : t.rows) {
    if (r[static_cast<std::size_t>(status)] != "diverged" &&
        !r[static_cast<std::size_t>(mse)].empty())
      continue;
    const std::string label = case_label(t, est, r);
    for (auto& p : panels) {
      if (p.label != label) continue;
      for (auto& s : p.series) s.diverged |= s.estimator == r[static_cast<std::size_t>(est)];
    }
  }
}

std::string number_or_missing(double v) {
  return std::isfinite(v) && v <= kLargest ? fmt::format("{}", v) : "?";
}

bool drawable(double v) { return std::isfinite(v) && v > 0.0 && v <= kLargest; }

// The points of a series the figure draws: every `step`-th and the last.
bool kept(std::size_t i, std::size_t count, std::size_t step) {
  return i % step == 0 || i + 1 == count;
}

// The y range of a view's series that did not diverge (band ends and means).
struct YRange {
  double lo = INFINITY, hi = 0.0;
  void add(double v) {
    if (!drawable(v)) return;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  bool empty() const { return !(lo <= hi); }
};

YRange y_range(const View& v, std::size_t step) {
  YRange r;
  for (std::size_t s = v.lo; s < v.hi; ++s) {
    const auto& series = v.panel->series[s];
    if (series.diverged) continue;
    for (std::size_t i = 0; i < series.points.size(); ++i) {
      if (!kept(i, series.points.size(), step)) continue;
      const auto& q = series.points[i];
      r.add(q[1]);
      if (std::isfinite(q[2])) r.add(q[1] + q[2]);
    }
  }
  return r;
}

bool diverged_in(const View& v) {
  for (std::size_t s = v.lo; s < v.hi; ++s) {
    if (v.panel->series[s].diverged) return true;
  }
  return false;
}

// One data block per drawn series of view v (gnuplot `index`); the band's lower edge is drawn
// to mean/1000 where mean - half-width is not positive (the axis is logarithmic).
std::string view_dat(const View& v, std::size_t step, std::size_t& index,
                     std::vector<std::size_t>& drawn, std::vector<bool>& banded,
                     std::string& left_out) {
  std::string dat;
  const Panel& p = *v.panel;
  for (std::size_t s = v.lo; s < v.hi; ++s) {
    const auto& pts = p.series[s].points;
    bool any = false, band_any = false;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      if (!kept(i, pts.size(), step)) continue;
      any = any || drawable(pts[i][1]);
      band_any = band_any || (drawable(pts[i][1]) && std::isfinite(pts[i][2]) &&
                              drawable(pts[i][1] + pts[i][2]));
    }
    if (!any) {
      left_out += (left_out.empty() ? "" : ", ") + p.series[s].estimator;
      continue;
    }
    dat += fmt::format("# index {}: {}{}\n# period mse lo hi\n", index++,
                       p.label.empty() ? "" : p.label + ", ", p.series[s].estimator);
    for (std::size_t i = 0; i < pts.size(); ++i) {
      if (!kept(i, pts.size(), step)) continue;
      const auto& q = pts[i];
      const double lo =
          std::isfinite(q[2]) ? (q[1] - q[2] > 0.0 ? q[1] - q[2] : q[1] / 1000.0) : std::nan("");
      const double hi = std::isfinite(q[2]) ? q[1] + q[2] : std::nan("");
      const bool band = drawable(q[1]) && drawable(hi);
      dat += fmt::format("{} {} {} {}\n", number_or_missing(q[0]),
                         drawable(q[1]) ? number_or_missing(q[1]) : "?",
                         band ? number_or_missing(lo) : "?", band ? number_or_missing(hi) : "?");
    }
    dat += "\n\n";
    drawn.push_back(s);
    banded.push_back(band_any);
  }
  return dat;
}

// The panels: each case whole, or split into groups when it has more than kMostSeries series.
std::vector<View> views_of(const std::vector<Panel>& all) {
  std::vector<View> views;
  for (const auto& p : all) {
    const std::size_t n = p.series.size(), groups = series_groups(n);
    for (std::size_t g = 0; g < groups; ++g)
      views.push_back(View{&p, g * n / groups, (g + 1) * n / groups});
  }
  return views;
}

// The `plot` command of one view whose series `drawn` (indices into the case's series) are the
// data blocks first, first + 1, ...; colours by place in the view.
std::string view_plot(const View& v, std::size_t first, const std::vector<std::size_t>& drawn,
                      const std::vector<bool>& banded, bool scaled) {
  std::string plot;
  for (std::size_t d = 0; d < drawn.size(); ++d) {
    const auto i = first + d;
    const Series& series = v.panel->series[drawn[d]];
    const std::string colour = gnuplot_colour(drawn[d] - v.lo);
    const std::string name = gnuplot_quote(
        series.estimator + (series.diverged && scaled ? " (diverged, off the scale)" : ""));
    if (banded[d]) {
      plot +=
          fmt::format("{}'plot_error_curve.dat' index {} using 1:3:4 with filledcurves {} notitle",
                      plot.empty() ? "" : ", \\\n       ", i, colour);
    }
    plot += fmt::format("{}'plot_error_curve.dat' index {} using 1:2 with lines lw 1.5 {} title {}",
                        plot.empty() ? "" : ", \\\n       ", i, colour, name);
  }
  return "  plot " + plot + "\n";
}

// The gnuplot text of one view (its title, y range and plot), its data blocks appended to
// `dat` from block `index` on.
std::string view_body(const View& v, std::size_t step, std::size_t& index, std::string& dat) {
  std::vector<std::size_t> drawn;
  std::vector<bool> banded;  // per drawn series: a band with at least one point (not R = 1)
  std::string left_out;
  const std::size_t first = index;
  dat += view_dat(v, step, index, drawn, banded, left_out);
  std::string title = v.title();
  if (!left_out.empty())
    title += fmt::format("{}no finite values (diverged): {}", title.empty() ? "" : "; ", left_out);
  std::string body = fmt::format("  set title {}\n", gnuplot_quote(title));
  // A diverged series out of the scale: the panel's y range is the other series'.
  const YRange yr = diverged_in(v) ? y_range(v, step) : YRange{};
  const bool scaled = !yr.empty();
  body += scaled ? fmt::format("  set yrange [{:.6g}:{:.6g}]\n", yr.lo / 1.5, yr.hi * 1.5)
                 : "  set autoscale y\n";
  if (drawn.empty()) {  // nothing to draw: an empty frame saying why
    return body +
           "  set label 1 'no finite values' at graph 0.5, 0.5 center\n  unset logscale y\n"
           "  plot [0:1] [0:1] 1/0 notitle\n  unset label 1\n  set logscale y\n";
  }
  return body + view_plot(v, first, drawn, banded, scaled);
}

}  // namespace

std::optional<Figure> error_curve_figure(const std::string& dir) {
  const std::filesystem::path path = std::filesystem::path(dir) / "error_curve.csv";
  if (!std::filesystem::exists(path)) return std::nullopt;
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  std::vector<Panel> all = read_panels(parse_csv(text.str(), path.string()));
  if (all.empty()) return std::nullopt;
  mark_diverged(dir, all);
  std::vector<View> views = views_of(all);
  const std::size_t total = views.size();
  if (views.size() > kMaxPanels) views.resize(kMaxPanels);
  std::size_t points = 0;
  for (const auto& p : all) {
    for (const auto& s : p.series) points = std::max(points, s.points.size());
  }
  const std::size_t step = std::max<std::size_t>(1, (points + kMostPoints - 1) / kMostPoints);
  Figure f;
  f.name = "plot_error_curve";
  f.kind = FigureKind::kPerEstimator;
  f.title = "run-averaged squared error |x - xhat|^2 against time, 95 % band";
  f.dat = fmt::format("# {} (from error_curve.csv{})\n", f.title,
                      step > 1 ? fmt::format("; one period in {} and the last", step) : "");
  const std::string shown =
      total > views.size()
          ? fmt::format(" (the first {} of {} panels; error_curve.csv has every one)", views.size(),
                        total)
          : "";
  std::string body = fmt::format("  set multiplot layout {},1 title {}\n", views.size(),
                                 gnuplot_quote(f.title + shown));
  body +=
      "  set grid\n  set logscale y\n  set format y '%g'\n  set key outside right top font ',8'\n  "
      "set xlabel 'period'\n"
      "  set ylabel 'mean |x - xhat|^2'\n  set style fill transparent solid 0.2 noborder\n";
  // The same plot area in every panel, whatever its legend's width.
  body += "  set lmargin at screen 0.09\n  set rmargin at screen 0.70\n";
  std::size_t index = 0;
  for (const auto& v : views) body += view_body(v, step, index, f.dat);
  if (!shown.empty()) f.dat += "# the figure shows" + shown + "\n";
  f.gp = gnuplot_script(f.name, f.title, 1000, static_cast<int>(320 * views.size() + 80), body);
  return f;
}

}  // namespace ncosim::sim
