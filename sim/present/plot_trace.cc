// sim/present/plot_trace.cc — see sim/present/plot_trace.h.
#include "sim/present/plot_trace.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string_view>
#include <vector>

#include "config/config.h"
#include "sim/analysis/output.h"

namespace ncosim::sim {

namespace fs = std::filesystem;
using namespace figure_text;  // sim/present/figure.h

namespace {

// The columns of trajectory.csv: period, states (and their physical coordinates), each
// estimator's estimate, each sensor's arrivals.
struct Trajectory {
  fs::path path;
  CsvTable t;
  int period = -1;
  std::vector<int> x, xphys;            // x1..xn and x<i>_physical (-1 when absent)
  std::vector<std::string> estimators;  // in column order
  std::vector<std::vector<int>> xhat;   // per estimator: <name>:xhat1 ..
  std::vector<std::string> sensors;
  std::vector<int> arrived;  // per sensor: arrived:<name>
};

Trajectory read_trajectory(const std::string& dir) {
  Trajectory tr;
  tr.path = fs::path(dir) / "trajectory.csv";
  const fs::path& p = tr.path;
  if (!fs::exists(p)) {
    throw config::ScenarioError(fmt::format(
        "--trace: {} does not exist (run the campaign with `ncosim run --trace`)", p.string()));
  }
  tr.t = parse_csv(read_file(p), p.string());
  const CsvTable& t = tr.t;
  for (int i = 1;; ++i) {
    const int c = t.column(fmt::format("x{}", i));
    if (c < 0) break;
    tr.x.push_back(c);
    tr.xphys.push_back(t.column(fmt::format("x{}_physical", i)));
  }
  if (tr.x.empty())
    throw config::ScenarioError(
        config::format_error(p.string(), 1, "", "expected columns x1 .. xn"));
  for (std::size_t c = 0; c < t.header.size(); ++c) {
    const std::string& h = t.header[c];
    if (h.rfind("arrived:", 0) == 0) {
      tr.sensors.push_back(h.substr(8));
      tr.arrived.push_back(static_cast<int>(c));
      continue;
    }
    const auto pos = h.rfind(":xhat");
    if (pos == std::string::npos || h.size() == pos + 5) continue;
    const std::string name = h.substr(0, pos);
    if (h.substr(pos + 5) == "1") {
      tr.estimators.push_back(name);
      tr.xhat.emplace_back();
    }
    if (!tr.xhat.empty() && tr.estimators.back() == name)
      tr.xhat.back().push_back(static_cast<int>(c));
  }
  tr.period = t.column("period");
  return tr;
}

// The rows of the periods from..from+periods-1; throws when there is none.
std::vector<const std::vector<std::string>*> trace_window(const Trajectory& tr,
                                                          const PlotOptions& opt) {
  std::vector<const std::vector<std::string>*> window;
  for (const auto& r : tr.t.rows) {
    const auto k = number(r[static_cast<std::size_t>(tr.period)]);
    if (k && *k >= static_cast<double>(opt.trace_from) &&
        *k < static_cast<double>(opt.trace_from) + static_cast<double>(opt.trace_periods)) {
      window.push_back(&r);
    }
  }
  if (window.empty()) {
    throw config::ScenarioError(
        fmt::format("--from {}: no period of {} in the window of {} periods", opt.trace_from,
                    tr.path.string(), opt.trace_periods));
  }
  return window;
}

// The trace .dat: period, x, every estimate and every arrival count per row. With `physical`,
// x is written as x_physical and each estimate of a state is shifted by (x_physical - x).
std::string trace_dat(const Trajectory& tr,
                      const std::vector<const std::vector<std::string>*>& window, bool physical,
                      const std::string& title) {
  const std::size_t n = tr.x.size();
  std::string dat = fmt::format("# {}\n# period", comment(title));
  for (std::size_t i = 0; i < n; ++i) dat += fmt::format(" x{}", i + 1);
  for (std::size_t e = 0; e < tr.estimators.size(); ++e) {
    for (std::size_t i = 0; i < tr.xhat[e].size(); ++i)
      dat += fmt::format(" [{}]:xhat{}", comment(tr.estimators[e]), i + 1);
  }
  for (const auto& s : tr.sensors) dat += fmt::format(" arrived:[{}]", comment(s));
  dat +=
      physical
          ? "\n# x and xhat in physical coordinates: xhat + (x_physical - x) from trajectory.csv\n"
          : "\n# numbers copied from trajectory.csv as written\n";
  for (const auto* rp : window) {
    const auto& r = *rp;
    dat += r[static_cast<std::size_t>(tr.period)];
    std::vector<double> offset(n, 0.0);
    for (std::size_t i = 0; i < n; ++i) {
      if (physical) {
        offset[i] = *number(r[static_cast<std::size_t>(tr.xphys[i])]) -
                    number(r[static_cast<std::size_t>(tr.x[i])]).value_or(0.0);
        dat += " " + r[static_cast<std::size_t>(tr.xphys[i])];
      } else {
        dat += " " + dat_field(r[static_cast<std::size_t>(tr.x[i])]);
      }
    }
    for (const auto& cols : tr.xhat) {
      for (std::size_t i = 0; i < cols.size(); ++i) {
        const std::string& v = r[static_cast<std::size_t>(cols[i])];
        if (physical && i < n && number(v)) {
          dat += fmt::format(" {:.9g}", *number(v) + offset[i]);
        } else {
          dat += " " + dat_field(v);
        }
      }
    }
    for (int a : tr.arrived) dat += " " + dat_field(r[static_cast<std::size_t>(a)]);
    dat += "\n";
  }
  return dat;
}

// Whether column c holds a finite number in some row of the window.
bool any_finite(const std::vector<const std::vector<std::string>*>& window, int c) {
  return std::any_of(window.begin(), window.end(), [&](const auto* r) {
    return number((*r)[static_cast<std::size_t>(c)]).has_value();
  });
}

// The trace gnuplot body: one panel per shown state (true x and every estimate), then one of
// the arrivals per sensor (dots where packets arrived, crosses where none did).
std::string trace_body(const Trajectory& tr,
                       const std::vector<const std::vector<std::string>*>& window,
                       std::size_t shown, const std::string& title) {
  const std::size_t n = tr.x.size();
  std::string body = fmt::format("  set multiplot layout {},1 title {}\n",
                                 shown + (tr.sensors.empty() ? 0 : 1), gnuplot_quote(title));
  body += "  set lmargin 12\n  set rmargin 30\n  set grid\n  set key outside right top font ',8'\n";
  std::size_t col = 2 + n;  // trace.dat's column of the first estimate
  std::vector<std::size_t> first_col;
  for (const auto& cols : tr.xhat) {
    first_col.push_back(col);
    col += cols.size();
  }
  for (std::size_t i = 0; i < shown; ++i) {
    body += fmt::format("  set ylabel {}\n", gnuplot_quote(fmt::format("x{}", i + 1)));
    // A series without a finite value in the window (a diverged estimate) is a legend entry saying
    // so: gnuplot warns about a data series without a valid point.
    std::string plot =
        any_finite(window, tr.x[i])
            ? fmt::format("'trace.dat' using 1:{} with lines lw 2 lc rgb 'black' title 'true x{}'",
                          2 + i, i + 1)
            : fmt::format(
                  "keyentry with lines lw 2 lc rgb 'black' title 'true x{}: no finite value'",
                  i + 1);
    bool drawn = any_finite(window, tr.x[i]);  // the last series read trace.dat ('' reads it again)
    for (std::size_t e = 0; e < tr.estimators.size(); ++e) {
      if (i >= tr.xhat[e].size()) continue;
      if (!any_finite(window, tr.xhat[e][i])) {
        plot += fmt::format(", \\\n       keyentry with lines {} title {}", gnuplot_colour(e),
                            gnuplot_quote(tr.estimators[e] + ": no finite value (diverged)"));
        continue;
      }
      plot += fmt::format(", \\\n       {} using 1:{} with lines {} title {}",
                          drawn ? "''" : "'trace.dat'", first_col[e] + i, gnuplot_colour(e),
                          gnuplot_quote(tr.estimators[e]));
      drawn = true;
    }
    body += drawn ? "  plot " + plot + "\n"
                  : "  set yrange [1:10]\n  plot " + plot + ", 1/0 notitle\n  set autoscale y\n";
  }
  if (!tr.sensors.empty()) {
    body += "  set ylabel 'packets'\n  set xlabel 'period'\n";
    body += fmt::format("  set yrange [-0.5:{}]\n  set ytics {}\n",
                        static_cast<double>(tr.sensors.size()) - 0.5, tics(tr.sensors));
    std::string plot;
    for (std::size_t s = 0; s < tr.sensors.size(); ++s) {
      const std::size_t c = col + s;
      plot += fmt::format(
          "{}'trace.dat' using 1:(${} > 0 ? {} : 1/0) with points pt 7 ps 0.5 lc rgb '#2ca02c' "
          "title {}",
          plot.empty() ? "" : ", \\\n       ", c, s, s == 0 ? "'packet(s) arrived'" : "''");
      plot += fmt::format(
          ", \\\n       '' using 1:(${} == 0 ? {} : 1/0) with points pt 2 ps 0.6 lc rgb '#d62728' "
          "title {}",
          c, s, s == 0 ? "'nothing arrived'" : "''");
    }
    body += "  plot " + plot + "\n";
  }
  return body;
}

}  // namespace

Figure trace_figure(const std::string& dir, const PlotOptions& opt) {
  const Trajectory tr = read_trajectory(dir);
  const auto window = trace_window(tr, opt);
  // Physical coordinates where the re-centred run has them over the whole window.
  bool physical = std::all_of(tr.xphys.begin(), tr.xphys.end(), [](int c) { return c >= 0; });
  const bool recentred = physical;
  for (const auto* r : window) {
    for (int c : tr.xphys)
      physical = physical && c >= 0 && number((*r)[static_cast<std::size_t>(c)]).has_value();
  }
  const std::size_t n = tr.x.size();
  const std::size_t shown = std::min<std::size_t>(n, 6);
  Figure f;
  f.name = "trace";
  f.kind = FigureKind::kTrace;
  const std::string title0 = scenario_title(dir);
  f.title = fmt::format(
      "run 0, periods {}..{}{}{}", (*window.front())[static_cast<std::size_t>(tr.period)],
      (*window.back())[static_cast<std::size_t>(tr.period)],
      recentred ? (physical ? ", physical coordinates (re-centring added back)"
                            : ", re-centred coordinates (the physical state exceeds 1e10 here)")
                : "",
      title0.empty() ? "" : " — " + title0);
  f.dat = trace_dat(tr, window, physical, f.title);
  if (n > shown) f.dat += fmt::format("# the figure shows x1..x{} of {} states\n", shown, n);
  f.gp = gnuplot_script(f.name, f.title, 1000, static_cast<int>(260 * (shown + 1) + 60),
                        trace_body(tr, window, shown, f.title));
  return f;
}

}  // namespace ncosim::sim
