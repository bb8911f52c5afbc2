// sim/present/plot.h — `ncosim plot DIR`: gnuplot figures of any output folder, shaped by the
// campaign (one case: the metric per estimator; one sweep key: the metric against it; two or more
// keys: one panel per value of the others), and `--trace`: run 0's state and estimates against
// time. Each figure is a .dat file (numbers copied from summary.csv / trajectory.csv as written)
// and a .gp script beside the images, so that a user can restyle it. Bad input (no summary.csv, an
// unknown metric or key) is a ScenarioError; a failing gnuplot is a std::runtime_error.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "sim/files/csv.h"

namespace ncosim::sim {

enum class FigureKind {
  kPerEstimator,  // one case: metric per estimator, CI bars, prediction beside
  kAgainstKey,    // one sweep key (or all but the panel key fixed): metric against the key
  kPanels,        // two or more keys: one panel per value of the panel key(s)
  kTrace,         // --trace: run 0's state and estimates against time
};
const char* figure_kind_name(FigureKind k);

struct PlotOptions {
  std::string metric = "mse";  // a numeric column of summary.csv
  std::string x_key;  // sweep key on the x axis (default: the first numeric key, else the first)
  std::string panel_key;      // sweep key of the panels (default: every other key together)
  std::string logx = "auto";  // auto | on | off
  std::string logy = "auto";
  std::vector<std::string> formats{"png", "svg"};
  bool trace = false;        // also the trace figure from trajectory.csv
  long trace_from = 0;       // first period of the trace window
  long trace_periods = 200;  // periods in the trace window
};

// One figure: its base name (files <name>.dat, <name>.gp, <name>.<format>) and content.
struct Figure {
  std::string name;
  FigureKind kind = FigureKind::kPerEstimator;
  std::string title;
  std::string dat, gp;
};

// The kind of the summary figure for this summary.csv and these options.
FigureKind summary_figure_kind(const CsvTable& summary, const PlotOptions& opt);

// Builds the figures of `dir` (reads summary.csv, and trajectory.csv when opt.trace).
std::vector<Figure> build_figures(const std::string& dir, const PlotOptions& opt);

// Writes the .dat and .gp files into `dir` and runs gnuplot there for `formats`.
// Returns the image paths written.
std::vector<std::string> render_figures(const std::string& dir, const std::vector<Figure>& figures,
                                        const std::vector<std::string>& formats);

// The error-curve figure (`plot_error_curve`) of a folder with error_curve.csv ([run] error_curve):
// per estimator the run-averaged squared error against time, its 95 % band shaded; one panel per
// case (at most six). nullopt when the folder has no error_curve.csv. (sim/present/plot_curve.cc)
std::optional<Figure> error_curve_figure(const std::string& dir);

// The gnuplot script of figure `name` around `body` (one pass per output format), and the line
// colour of the e-th series: shared by every figure of `ncosim plot`.
std::string gnuplot_script(const std::string& name, const std::string& what, int width, int height,
                           const std::string& body);
std::string gnuplot_colour(std::size_t e);

// Quoted gnuplot string literal (single quotes, '' for a quote; line breaks become spaces).
std::string gnuplot_quote(const std::string& s);

// `ncosim plot`: builds, writes and renders; prints what was written. Returns the exit status.
int plot_command(const std::string& dir, const PlotOptions& opt);

}  // namespace ncosim::sim
