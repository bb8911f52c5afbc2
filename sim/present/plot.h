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
#include "sim/present/figure.h"

namespace ncosim::sim {

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

// `ncosim plot`: builds, writes and renders; prints what was written. Returns the exit status.
int plot_command(const std::string& dir, const PlotOptions& opt);

}  // namespace ncosim::sim
