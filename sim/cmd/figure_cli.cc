// sim/cmd/figure_cli.cc — the `plot` and `report` subcommands' options.
#include "sim/cmd/figure_cli.h"

#include <fmt/format.h>

#include <sstream>

#include "config/config.h"
#include "sim/files/output_set.h"

namespace ncosim::sim {

namespace {

void add_shape_options(CLI::App* sub, FigureCommands& fc, PlotOptions& o) {
  sub->add_option("DIR", fc.dir, "output folder of `ncosim run` (holds summary.csv)")->required();
  sub->add_option("--metric", o.metric, "numeric column of summary.csv to plot (default mse)");
  sub->add_option("--x", o.x_key,
                  "sweep key on the x axis (default: the first numeric key, else the first key)");
  sub->add_option("--panel", o.panel_key,
                  "sweep key of the panels (default: every key but the x key)");
  sub->add_option("--logx", o.logx, "log x axis: auto (range of 100 or more), on, off")
      ->check(CLI::IsMember({"auto", "on", "off"}));
  sub->add_option("--logy", o.logy, "log y axis: auto (range of 100 or more), on, off")
      ->check(CLI::IsMember({"auto", "on", "off"}));
  sub->add_flag("--trace", o.trace,
                "also the trace figure of run 0 (needs trajectory.csv: `ncosim run --trace`)");
  sub->add_option("--from", o.trace_from, "first period of the trace window (default 0)")
      ->check(CLI::Range(0L, 4'000'000'000'000L));
  sub->add_option("--periods", o.trace_periods, "periods in the trace window (default 200)")
      ->check(CLI::Range(1L, 10'000'000L));
}

}  // namespace

void add_figure_commands(CLI::App& app, FigureCommands& fc) {
  fc.plot = app.add_subcommand(
      "plot", "figures of an output folder (gnuplot; .dat and .gp kept beside the images)");
  add_shape_options(fc.plot, fc, fc.plot_options);
  fc.plot->add_option("--format", fc.formats,
                      "image formats, comma-separated: png, svg (default png,svg)");
  fc.report = app.add_subcommand("report", "one self-contained report.html of an output folder");
  add_shape_options(fc.report, fc, fc.report_options.plot);
  fc.report->add_option("--out", fc.report_options.out, "the HTML file (default DIR/report.html)");
  fc.report->add_flag("--no-figures", fc.no_figures, "tables only (no gnuplot)");
}

std::optional<int> run_figure_commands(FigureCommands& fc) {
  const bool reads =
      (fc.plot != nullptr && fc.plot->parsed()) || (fc.report != nullptr && fc.report->parsed());
  if (reads) restore_interrupted_write(fc.dir);  // sim/files/output_set.h
  if (fc.plot != nullptr && fc.plot->parsed()) {
    fc.plot_options.formats.clear();
    std::stringstream ss(fc.formats);
    for (std::string f; std::getline(ss, f, ',');) {
      if (f != "png" && f != "svg")
        throw config::ScenarioError(fmt::format("--format '{}': expected png, svg or png,svg", f));
      fc.plot_options.formats.push_back(f);
    }
    if (fc.plot_options.formats.empty())
      throw config::ScenarioError("--format: expected png, svg or png,svg");
    return plot_command(fc.dir, fc.plot_options);
  }
  if (fc.report != nullptr && fc.report->parsed()) {
    fc.report_options.figures = !fc.no_figures;
    return report_command(fc.dir, fc.report_options);
  }
  return std::nullopt;
}

}  // namespace ncosim::sim
