// sim/present/plot_curve.cc — the error-curve figure of `ncosim plot`: error_curve.csv ([run]
// error_curve) as one curve per estimator against the period, its 95 % band shaded, one panel
// per case. The numbers are copied from the CSV as written (values above 1e150, a diverged
// estimator, are drawn as missing); a series without a single such value is left out and named
// in the panel's title, so gnuplot never meets an empty series.
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

constexpr std::size_t kMaxPanels = 6;
// Values above this are drawn as missing: the run recorder's divergence threshold (|e|^2 > 1e150),
// and far beyond it gnuplot's axis range overflows ("y axis range undefined or overflow").
constexpr double kLargest = 1e150;

struct Series {
  std::string estimator;
  std::vector<std::array<double, 3>> points;  // period, mean, half-width (NaN: none)
  std::vector<double> periods;
};

struct Panel {
  std::string label;  // the case's sweep values ("" for one case)
  std::vector<Series> series;
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

std::vector<Panel> read_panels(const CsvTable& t) {
  const int est = t.column("estimator"), period = t.column("period"), mse = t.column("mse"),
            ci = t.column("mse_ci95");
  if (est < 0 || period < 0 || mse < 0 || ci < 0) {
    throw config::ScenarioError(
        "error_curve.csv: expected the columns estimator, period, mse and mse_ci95");
  }
  std::vector<Panel> panels;
  for (const auto& r : t.rows) {
    std::string label;
    for (int i = 0; i < est; ++i) {
      label += fmt::format("{}{} = {}", i ? ", " : "", t.header[static_cast<std::size_t>(i)],
                           r[static_cast<std::size_t>(i)]);
    }
    if (panels.empty() || panels.back().label != label) panels.push_back(Panel{label, {}});
    auto& series = panels.back().series;
    const std::string& name = r[static_cast<std::size_t>(est)];
    if (series.empty() || series.back().estimator != name) series.push_back(Series{name, {}, {}});
    series.back().points.push_back({parse(r[static_cast<std::size_t>(period)]),
                                    parse(r[static_cast<std::size_t>(mse)]),
                                    parse(r[static_cast<std::size_t>(ci)])});
  }
  return panels;
}

std::string number_or_missing(double v) {
  return std::isfinite(v) && v <= kLargest ? fmt::format("{}", v) : "?";
}

bool drawable(double v) { return std::isfinite(v) && v > 0.0 && v <= kLargest; }

// One data block per drawn series (gnuplot `index`); the band's lower edge is drawn to mean/1000
// where mean - half-width is not positive (the axis is logarithmic).
std::string panel_dat(const Panel& p, std::size_t& index, std::vector<std::size_t>& drawn,
                      std::vector<bool>& banded, std::string& left_out) {
  std::string dat;
  for (std::size_t s = 0; s < p.series.size(); ++s) {
    const auto& pts = p.series[s].points;
    const bool any =
        std::any_of(pts.begin(), pts.end(), [](const auto& q) { return drawable(q[1]); });
    if (!any) {
      left_out += (left_out.empty() ? "" : ", ") + p.series[s].estimator;
      continue;
    }
    dat += fmt::format("# index {}: {}{}\n# period mse lo hi\n", index++,
                       p.label.empty() ? "" : p.label + ", ", p.series[s].estimator);
    for (const auto& q : pts) {
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
    banded.push_back(std::any_of(pts.begin(), pts.end(), [](const auto& q) {
      return drawable(q[1]) && std::isfinite(q[2]) && drawable(q[1] + q[2]);
    }));
  }
  return dat;
}

}  // namespace

std::optional<Figure> error_curve_figure(const std::string& dir) {
  const std::filesystem::path path = std::filesystem::path(dir) / "error_curve.csv";
  if (!std::filesystem::exists(path)) return std::nullopt;
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  const std::vector<Panel> all = read_panels(parse_csv(text.str(), path.string()));
  if (all.empty()) return std::nullopt;
  const std::size_t panels = std::min(all.size(), kMaxPanels);
  Figure f;
  f.name = "plot_error_curve";
  f.kind = FigureKind::kPerEstimator;
  f.title = "run-averaged squared error |x - xhat|^2 against time, 95 % band";
  f.dat = fmt::format("# {} (from error_curve.csv)\n", f.title);
  std::string body =
      fmt::format("  set multiplot layout {},1 title {}\n", panels, gnuplot_quote(f.title));
  body +=
      "  set grid\n  set logscale y\n  set format y '%g'\n  set key outside right top font ',8'\n  "
      "set xlabel 'period'\n"
      "  set ylabel 'mean |x - xhat|^2'\n  set style fill transparent solid 0.2 noborder\n";
  std::size_t index = 0;
  for (std::size_t p = 0; p < panels; ++p) {
    std::vector<std::size_t> drawn;
    std::vector<bool> banded;  // per drawn series: a band with at least one point (not R = 1)
    std::string left_out;
    const std::size_t first = index;
    f.dat += panel_dat(all[p], index, drawn, banded, left_out);
    std::string title = all[p].label;
    if (!left_out.empty())
      title +=
          fmt::format("{}no finite values (diverged): {}", title.empty() ? "" : "; ", left_out);
    body += fmt::format("  set title {}\n", gnuplot_quote(title));
    if (drawn.empty()) {  // nothing to draw: an empty frame saying why
      body +=
          "  set label 1 'no finite values' at graph 0.5, 0.5 center\n  unset logscale y\n"
          "  plot [0:1] [0:1] 1/0 notitle\n  unset label 1\n  set logscale y\n";
      continue;
    }
    std::string plot;
    for (std::size_t d = 0; d < drawn.size(); ++d) {
      const auto i = first + d;
      const std::string colour = gnuplot_colour(drawn[d]);
      const std::string name = gnuplot_quote(all[p].series[drawn[d]].estimator);
      if (banded[d]) {
        plot += fmt::format(
            "{}'plot_error_curve.dat' index {} using 1:3:4 with filledcurves {} notitle",
            plot.empty() ? "" : ", \\\n       ", i, colour);
      }
      plot +=
          fmt::format("{}'plot_error_curve.dat' index {} using 1:2 with lines lw 1.5 {} title {}",
                      plot.empty() ? "" : ", \\\n       ", i, colour, name);
    }
    body += "  plot " + plot + "\n";
  }
  if (all.size() > panels)
    f.dat += fmt::format("# the figure shows the first {} of {} cases\n", panels, all.size());
  f.gp = gnuplot_script(f.name, f.title, 1000, static_cast<int>(320 * panels + 80), body);
  return f;
}

}  // namespace ncosim::sim
